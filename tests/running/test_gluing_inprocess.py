"""The T-T algorithm on in-process physics cores (no FMU): kinematic measures,
multiple connections, flexible joint laws, against monolithic models."""
import numpy as np
import pytest

from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain
from dsim.master.errors import SimulationError
from dsim.master.planning.assembly import glue_cores
from dsim.master.scene import Joint, MasterSettings

H, STOP = 0.01, 3.0


def chain(n, **values):
    params = ChainParameters(n=n)
    for key, value in values.items():
        target = getattr(params, key)
        if isinstance(target, np.ndarray):
            target[: len(value)] = value
        else:
            setattr(params, key, value)
    return SpringMassChain(params)


def march(gluing, record, steps=round(STOP / H)):
    history = []
    for i in range(steps):
        gluing.step(i * H, H, i + 1)
        history.append(record())
    return np.array(history)


def reference(core, record, steps=round(STOP / H)):
    core.initialize(0.0)
    history = []
    for i in range(steps):
        core.step(i * H, H)
        history.append(record(core))
    return np.array(history)


@pytest.mark.parametrize("measure", ["displacement", "velocity", "acceleration", "penalized"])
def test_fixed_joint_under_every_measure_equals_the_merged_model(measure):
    """With trapezoidal subsystems, compatibility of v or a (started compatible)
    implies compatibility of u: every measure must give the merged model."""
    left = chain(1, m=[10.0], k_ground=[100.0])
    right = chain(2, m=[10.0, 10.0], k=[100.0], F0=[0.0, 10.0])
    joint = Joint("j", ("left", "P"), ("right", "Q"), ("x",), "fixed", measure,
                  xi=0.7, omega=50.0)
    gluing = glue_cores({"left": left, "right": right}, [joint], MasterSettings(
        step=H, tolerance=1e-11))
    glued = march(gluing, lambda: right.x[1])
    merged = chain(2, m=[20.0, 10.0], k_ground=[100.0], k=[100.0], F0=[0.0, 10.0])
    expected = reference(merged, lambda c: c.x[1])
    assert np.max(np.abs(glued - expected)) < 1e-9 * np.max(np.abs(expected))
    assert np.max(np.abs(left.x - right.x[0])) < 1e-9


def test_port_in_two_joints_receives_the_sum_of_their_forces():
    """Multiple connection (eq. 4.10): hub.P glued to a.P and to b.P."""
    hub = chain(1, m=[1.0], k_ground=[100.0], Fa=[5.0], omega=[7.0])
    a = chain(1, m=[2.0], k_ground=[50.0])
    b = chain(1, m=[3.0], k_ground=[10.0], F0=[1.0])
    joints = [Joint("ja", ("hub", "P"), ("a", "P"), ("x",)),
              Joint("jb", ("hub", "P"), ("b", "P"), ("x",))]
    gluing = glue_cores({"hub": hub, "a": a, "b": b}, joints, MasterSettings(step=H))
    glued = march(gluing, lambda: np.r_[hub.x[0], a.x[0], b.x[0], gluing.forces])
    merged = chain(1, m=[6.0], k_ground=[160.0], Fa=[5.0], omega=[7.0], F0=[1.0])
    expected = reference(merged, lambda c: c.x[0])
    assert np.max(np.abs(glued[:, :3] - expected[:, None])) < 1e-9
    # the joint force into b is what b's own equation needs: m a + k x = F0 + f
    accel = (glued[2:, 2] - 2 * glued[1:-1, 2] + glued[:-2, 2]) / H ** 2
    assert np.all(np.isfinite(accel)) and np.max(np.abs(glued[:, 4])) > 0.1


@pytest.mark.parametrize("measure", ["displacement", "velocity", "acceleration"])
def test_nonlinear_flexible_joint_under_several_measures(measure):
    """Eq. 5.37 with the nonlinear law, the joint extension integrated by the
    master (eqs. 5.2-5.18) whatever the measure."""
    law = dict(k0=(100.0,), k1=(1000.0,), c0=(14.14,), c1=(14140.0,))
    left = chain(1, m=[10.0], k_ground=[100.0])
    right = chain(2, m=[10.0, 10.0], k=[100.0], F0=[0.0, 10.0])
    joint = Joint("j", ("left", "P"), ("right", "Q"), ("x",), "flexible", measure, **law)
    gluing = glue_cores({"left": left, "right": right}, [joint],
                        MasterSettings(step=H, tolerance=1e-12))
    glued = march(gluing, lambda: right.x[1])
    whole = chain(3, m=[10.0] * 3, k_ground=[100.0], k=[100.0, 100.0], k1=[1000.0],
                  c=[14.14], c1=[14140.0], F0=[0.0, 0.0, 10.0])
    expected = reference(whole, lambda c: c.x[2])
    assert np.max(np.abs(glued - expected)) < 1e-8 * np.max(np.abs(expected))


def test_joint_with_nothing_to_move_is_a_clear_failure():
    """Gluing two ports that cannot move (no mass response: infinite mass is
    impossible, so use a dof the joint forces cannot change): singular Lambda."""
    left = chain(1, m=[1.0], k_ground=[1.0])
    right = chain(1, m=[1.0], k_ground=[1.0])
    joint = Joint("j", ("left", "P"), ("right", "P"), ("x",), "fixed", "velocity")
    settings = MasterSettings(step=H, perturbation=0.0)  # zero perturbation: G = 0/0
    gluing = glue_cores({"left": left, "right": right}, [joint], settings)
    left.v[:] = 1.0  # start incompatible so the first residual is not zero
    with pytest.raises(SimulationError):
        gluing.step(0.0, H, 1)
