"""Checks of the planar multibody core (fmus/linkage) against closed forms and itself."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fmus.linkage import Body, Linkage, Mechanism, Revolute, SpringDamper
from fmus.linkage.scenes import CRANK_SLIDER_PARTS, crank_angle, crank_slider, four_bar
from tests.gluing_helpers import march, penalized_joint

G = 9.81


def _upward_crossings(t, x):
    """Times (s) where x crosses zero upwards, by linear interpolation."""
    i = np.nonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))[0]
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def test_compound_pendulum_period():
    """A uniform bar (L = 1 m) pinned at one end swings with T = 2 pi sqrt(2 L / (3 g))."""
    length, mass, amplitude, h = 1.0, 2.0, 0.01, 1e-3
    theta0 = -math.pi / 2 + amplitude
    mech = Mechanism(
        bodies=[Body("bar", mass, mass * length ** 2 / 12.0,
                     x=0.5 * length * math.cos(theta0), y=0.5 * length * math.sin(theta0),
                     theta=theta0)],
        revolutes=[Revolute("pivot", "bar", (-0.5 * length, 0.0), None, (0.0, 0.0))],
        gravity=(0.0, -G))
    bar = Linkage(mech)
    bar.initialize(0.0)
    times, swing = [0.0], [amplitude]
    for n in range(3000):
        bar.step(n * h, h)
        times.append((n + 1) * h)
        swing.append(bar.q[0, 2] + math.pi / 2)
    crossings = _upward_crossings(np.array(times), np.array(swing))
    period = float(np.mean(np.diff(crossings)))
    exact = 2 * math.pi * math.sqrt(2 * length / (3 * G))
    assert len(crossings) >= 2
    assert abs(period / exact - 1.0) < 1e-4          # brief: 0.5 %; measured ~1e-6
    assert bar.constraint_violation() < 1e-9
    # The pivot carries weight plus centripetal load: mean vertical reaction ~ m g.
    assert bar.reactions()["pivot.f_y"] == pytest.approx(mass * G, rel=1e-3)


def test_spring_mass_frequency_and_decay():
    """A body hung on a spring-damper from a ground point: damped frequency and decay."""
    k, c, m = 400.0, 4.0, 1.0
    mech = Mechanism(bodies=[Body("mass", m, 1.0, y=-1.0 - m * G / k - 0.01)],
                     springs=[SpringDamper("spring", "mass", (0.0, 0.0), None, (0.0, 0.0),
                                           k, c, length0=1.0)],
                     gravity=(0.0, -G))
    body = Linkage(mech)
    body.initialize(0.0)
    h = 1e-3
    times, y = [0.0], [-0.01]
    for n in range(3000):
        body.step(n * h, h)
        times.append((n + 1) * h)
        y.append(body.q[0, 1] + 1.0 + m * G / k)
    y = np.array(y)
    crossings = _upward_crossings(np.array(times), y)
    zeta = c / (2 * math.sqrt(k * m))
    wd = math.sqrt(k / m) * math.sqrt(1 - zeta ** 2)
    assert np.mean(np.diff(crossings)) == pytest.approx(2 * math.pi / wd, rel=1e-4)
    # Logarithmic decrement between successive maxima: zeta w_n T_d.
    peaks = np.nonzero((y[1:-1] > y[:-2]) & (y[1:-1] >= y[2:]) & (y[1:-1] > 0))[0] + 1
    decrement = np.mean(np.log(y[peaks[:-1]] / y[peaks[1:]]))
    assert decrement == pytest.approx(zeta * math.sqrt(k / m) * 2 * math.pi / wd, rel=1e-3)


def test_crank_slider_kinematics_closed_form():
    """Slider position of the driven crank slider: x = l1 cos th + sqrt(l2^2 - (l1 sin th)^2)."""
    whole = crank_slider("whole")
    whole.initialize(0.0)
    h, worst, worst_violation = 1e-3, 0.0, 0.0
    for n in range(3000):
        whole.step(n * h, h)
        th = crank_angle((n + 1) * h)
        exact = 3.0 * math.cos(th) + math.sqrt(36.0 - (3.0 * math.sin(th)) ** 2)
        worst = max(worst, abs(whole.q[2, 0] - exact) / abs(exact))
        worst_violation = max(worst_violation, whole.constraint_violation())
    assert worst < 1e-6                               # measured ~4e-8
    assert worst_violation < 1e-6
    assert whole.v[0, 2] == pytest.approx(2 * math.pi, rel=1e-6)   # crank at full speed


def test_index3_has_parasitic_force_oscillation():
    """Why Baumgarte is the default: on the index-3 form the trapezoidal rule lets the
    joint force oscillate step to step (period 2h); the stabilised form does not."""
    roughness = {}
    for formulation in ("baumgarte", "index3"):
        whole = crank_slider("whole", formulation=formulation)
        whole.initialize(0.0)
        force = []
        for n in range(1500):
            whole.step(n * 1e-3, 1e-3)
            force.append(whole.reactions()["A.f_y"])
        roughness[formulation] = np.max(np.abs(np.diff(force, 2)))
    assert roughness["baumgarte"] < 50.0            # measured 14 N (peak |A.f_y| 2.8e4)
    assert roughness["index3"] > 100 * roughness["baumgarte"]   # measured 2.0e4 N


def _run_some(core, start, steps, h):
    for n in range(steps):
        core.step(start + n * h, h)


@pytest.mark.parametrize("part", ("whole",) + CRANK_SLIDER_PARTS)
def test_rollback_bit_for_bit(part):
    core = crank_slider(part)
    core.initialize(0.0)
    core.set_interface_forces(np.linspace(10.0, 40.0, len(core.interface)))
    h = 1e-3
    _run_some(core, 0.0, 600, h)
    saved = core.get_state()
    _run_some(core, 0.6, 7, h)
    first = [x.copy() for x in core.interface_kinematics()] + [core.q.copy(), core.lam.copy()]
    # Wreck the state and the inputs, then restore and repeat.
    core.set_interface_forces(np.zeros(len(core.interface)))
    _run_some(core, 0.607, 3, h)
    core.set_state(saved)
    saved["q"][:] = 123.0          # the core must not share memory with a saved state
    _run_some(core, 0.6, 7, h)
    again = [x.copy() for x in core.interface_kinematics()] + [core.q, core.lam]
    for x, y in zip(first, again):
        assert np.array_equal(x, y)


def test_glued_parts_match_whole_crank_slider():
    """Crank, coupler and slider glued at A and B with the penalized measure (the
    cores' own Baumgarte row) reproduce the monolithic joint forces."""
    h, steps = 1e-3, 500
    whole = crank_slider("whole")
    whole.initialize(0.0)
    reference = [np.zeros(4)]
    for n in range(steps):
        whole.step(n * h, h)
        r = whole.reactions()
        reference.append(np.array([r["A.f_x"], r["A.f_y"], r["B.f_x"], r["B.f_y"]]))
    reference = np.array(reference)
    parts = {p: crank_slider(p) for p in CRANK_SLIDER_PARTS}
    rows = whole.row_coefficients
    forces, _ = march(parts, [penalized_joint("A", ("crank", "A"), ("coupler", "A"), rows),
                              penalized_joint("B", ("coupler", "B"), ("slider", "P"), rows)],
                      h, steps, tolerance=1e-7)
    peak = np.max(np.abs(reference))
    assert peak > 1e4                                  # a real load, not zeros
    assert np.max(np.abs(forces - reference)) < 1e-6 * peak   # measured ~3e-9
    # And the slider went where the whole model's slider went.
    assert parts["slider"].q[0, 0] == pytest.approx(whole.q[2, 0], abs=1e-9)


def test_four_bar_passes_singular_configuration():
    """The monolithic parallelogram at H = 0.01 passes both collinear positions:
    the coupler keeps translating (angle 0) and the rocker stays parallel to the crank."""
    bar = four_bar("whole")
    bar.initialize(0.0)
    worst = 0.0
    for n in range(100):
        bar.step(n * 0.01, 0.01)
        worst = max(worst, abs(bar.q[1, 2]), abs(bar.q[2, 2] - bar.q[0, 2]))
    assert bar.q[0, 2] == pytest.approx(math.pi / 4 + 2 * math.pi, rel=1e-6)
    assert worst < 1e-9
