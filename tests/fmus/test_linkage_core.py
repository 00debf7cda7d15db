"""Checks of the planar multibody core (fmus/linkage) against closed forms and itself."""
from __future__ import annotations

import math

import numpy as np
import pytest

from dsim.fmus.linkage import Body, Linkage, Mechanism, Revolute, SpringDamper
from dsim.fmus.linkage.scenes import CRANK_SLIDER_PARTS, crank_angle, crank_slider, four_bar
from tests.support.gluing import crank_slider_reactions, march, penalized_joint

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
    reference, whole = crank_slider_reactions(steps, h)
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


# --- the generalized-alpha rule (fmus/generalized_alpha.py) ------------------------------

def _spring_mass(stiffness, spectral_radius):
    """A 1 kg body on a spring to ground (no gravity), 0.01 m from rest length."""
    mech = Mechanism(bodies=[Body("mass", 1.0, 1.0, x=1.01)],
                     springs=[SpringDamper("spring", "mass", (0.0, 0.0), None, (0.0, 0.0),
                                           stiffness, 0.0, length0=1.0)])
    body = Linkage(mech, spectral_radius=spectral_radius)
    body.initialize(0.0)
    return body


@pytest.mark.parametrize("spectral_radius", [1.0, 0.5, 0.0])
def test_generalized_alpha_is_second_order(spectral_radius):
    """x(1 s) of an undamped oscillator (w = 20 rad/s) against cos(w t): the observed
    order, the slope of log error over log h, is 2 for every spectral radius."""
    errors, sizes = [], np.array([4e-3, 2e-3, 1e-3])
    for h in sizes:
        body = _spring_mass(400.0, spectral_radius)
        for n in range(round(1.0 / h)):
            body.step(n * h, h)
        errors.append(abs(body.q[0, 0] - 1.0 - 0.01 * math.cos(20.0)))
    slope = np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.06)          # measured 1.95 .. 2.00


def test_generalized_alpha_damps_what_the_step_cannot_resolve():
    """A mode with w h = 10: the trapezoidal rule keeps its amplitude, rho_inf = 0.5
    takes it down by about 0.5 per step, rho_inf = 0 removes it at once."""
    left = {}
    for rho in (1.0, 0.5, 0.0):
        body = _spring_mass(1e8, rho)
        swing = []
        for n in range(30):
            body.step(n * 1e-3, 1e-3)
            swing.append(abs(body.q[0, 0] - 1.0) / 0.01)
        left[rho] = max(swing[-10:])
    assert left[1.0] > 0.5                                # measured 0.75
    assert left[0.5] < 1e-3                               # measured 1.0e-4
    assert left[0.0] < 1e-12                              # measured 0


def test_the_general_formulas_tend_to_the_trapezoidal_rule():
    """Just below rho_inf = 1 the generalized-alpha formulas (not the trapezoidal code
    path that rho_inf = 1 takes) give the trapezoidal rule's crank slider."""
    results = []
    for rho in (1.0, 1.0 - 1e-9):
        whole = crank_slider("whole", spectral_radius=rho)
        whole.initialize(0.0)
        for n in range(300):
            whole.step(n * 1e-3, 1e-3)
        results.append(np.concatenate((whole.q.ravel(), whole.v.ravel())))
    assert np.max(np.abs(results[1] - results[0])) < 1e-8


def test_index3_joints_hold_position_level_rows_and_generalized_alpha_smooths_them():
    """The whole four bar with revolutes A and B as position-level rows (the twin of
    fixed glue joints on the displacement measure) through its first two singular
    points: A and B stay closed to round-off; under the trapezoidal rule their force
    oscillates step to step to many times the true peak, under generalized-alpha
    (rho_inf = 0.3) it stays with the Baumgarte four bar's."""
    peak = {}
    for rho in (1.0, 0.3, "baumgarte"):
        options = {} if rho == "baumgarte" else dict(index3_joints=("A", "B"),
                                                     spectral_radius=rho)
        bar = four_bar("whole", **options)
        bar.initialize(0.0)
        forces, gap = [], 0.0
        for n in range(100):
            bar.step(n * 0.01, 0.01)
            forces.append(math.hypot(bar.reactions()["A.f_x"], bar.reactions()["A.f_y"]))
            if rho != "baumgarte":
                phi, _ = bar.constraints.position(bar.q, bar.time)
                rows = [r0 + k for _, name, r0 in bar.constraints.groups if name in "AB"
                        for k in (0, 1)]
                gap = max(gap, float(np.max(np.abs(phi[rows]))))
        peak[rho] = max(forces)
        if rho != "baumgarte":
            assert gap < 1e-12                            # m
    assert peak["baumgarte"] == pytest.approx(40.1, rel=0.01)    # N
    assert peak[1.0] > 10 * peak["baumgarte"]             # measured 46 times
    assert peak[0.3] == pytest.approx(peak["baumgarte"], rel=0.03)   # measured 1.7 %
    with pytest.raises(ValueError, match="index3_joints: no joint named C"):
        four_bar("whole", index3_joints=("A", "C"))


def test_rollback_bit_for_bit_under_generalized_alpha():
    """The pseudo-acceleration is part of the state: restoring and repeating steps of a
    damped part reproduces them bit for bit."""
    core = four_bar("coupler", spectral_radius=0.3)
    core.initialize(0.0)
    core.set_interface_forces(np.array([30.0, -20.0, -30.0, 20.0]))
    _run_some(core, 0.0, 20, 0.01)
    saved = core.get_state()
    _run_some(core, 0.2, 5, 0.01)
    first = [core.q.copy(), core.v.copy(), core.a.copy(), core.pseudo.copy()]
    _run_some(core, 0.25, 3, 0.01)
    core.set_state(saved)
    _run_some(core, 0.2, 5, 0.01)
    for x, y in zip(first, [core.q, core.v, core.a, core.pseudo]):
        assert np.array_equal(x, y)
    assert not np.array_equal(core.pseudo, core.a)       # it is a state of its own
