"""Checks of the flexible link (floating frame + Partitioned Iteration Method)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sla

from dsim.fmus.flexible_link import FlexibleLink
from dsim.fmus.linkage.scenes import crank_slider
from tests.support.gluing import crank_slider_reactions, march, penalized_joint

STEEL = dict(length=6.0, density=7850.0, area=0.01, young=210e9, second_moment=0.1 ** 4 / 12)


def _euler_bernoulli_free_free(length, density, area, young, second_moment):
    """First free-free bending frequency (Hz): 22.373 / (2 pi L^2) sqrt(EI / (rho A))."""
    return 22.373 / (2 * math.pi * length ** 2) * math.sqrt(young * second_moment / (density * area))


def test_first_free_free_frequency_matches_euler_bernoulli():
    link = FlexibleLink(**STEEL)
    exact = _euler_bernoulli_free_free(**STEEL)
    first = link.natural_frequencies(3)[0]
    assert exact == pytest.approx(14.768, abs=1e-3)
    assert abs(first / exact - 1) < 1e-3       # brief: 1 %; measured 2.6e-4 (6 elements)
    finer = FlexibleLink(**STEEL, elements=12).natural_frequencies(1)[0]
    assert abs(finer / exact - 1) < abs(first / exact - 1) / 8   # Hermite: ~h^4


def test_free_vibration_period_in_time():
    """Released from its first bending mode shape, the free link vibrates at that
    frequency and its reference frame stays still (no rigid content)."""
    link = FlexibleLink(**STEEL)
    b = link.beam
    w2, modes = sla.eigh(b.stiffness, b.mass)
    shape = modes[:, 3] * 1e-3 / np.max(np.abs(modes[1::3, 3]))
    state = link.get_state()
    state["qf"] = shape
    link.set_state(state)
    link.initialize(0.0)
    h, steps = 2e-4, 1000
    times, tip = [0.0], [link.qf[1]]
    for n in range(steps):
        link.step(n * h, h)
        times.append((n + 1) * h)
        tip.append(link.qf[1])
    t, y = np.array(times), np.array(tip)
    i = np.nonzero((y[:-1] < 0) & (y[1:] >= 0))[0]
    crossings = t[i] - y[i] * h / (y[i + 1] - y[i])
    frequency = 1.0 / np.mean(np.diff(crossings))
    assert frequency == pytest.approx(np.sqrt(w2[3]) / (2 * math.pi), rel=1e-4)
    out = link.outputs()
    assert abs(out["reference.x"]) < 1e-12 and abs(out["reference.theta"]) < 1e-12
    assert out["mean_axis_violation"] < 1e-10


def _spin_up(link, steps=1000, h=1e-3):
    forces = np.array([-50.0, -300.0, 80.0, 300.0])   # a couple plus a net pull in x
    link.set_interface_forces(forces)
    link.initialize(0.0)
    for n in range(steps):
        link.step(n * h, h)
    return link.interface_kinematics()


def test_stiff_link_moves_like_the_rigid_coupler():
    """Under the same port forces (held from t = 0) the stiff flexible link (E x 1000,
    light stiffness damping) and the rigid coupler part end up at the same places
    with the same velocities after 1 s; the steel link measurably does not."""
    rigid = _spin_up(crank_slider("coupler"))
    stiff = _spin_up(FlexibleLink(**{**STEEL, "young": 210e12}, x=6.0, stiffness_damping=1e-4))
    steel = _spin_up(FlexibleLink(**STEEL, x=6.0))
    assert np.max(np.abs(rigid[0] - stiff[0])) < 1e-6     # m; measured 6e-8
    assert np.max(np.abs(rigid[1] - stiff[1])) < 1e-5     # m/s of ~3; measured 2e-6
    assert np.max(np.abs(rigid[0] - steel[0])) > 1e-5     # m; measured 1.3e-4
    # (Accelerations are not compared: the suddenly applied load starts elastic
    # vibration that the trapezoidal rule does not damp, see docs/linkage.md.)


def test_rollback_bit_for_bit():
    link = FlexibleLink(**STEEL, x=6.0, omega=1.0)
    link.set_interface_forces([10.0, -20.0, 30.0, 40.0])
    link.initialize(0.0)
    h = 1e-3
    for n in range(100):
        link.step(n * h, h)
    saved = link.get_state()
    for n in range(5):
        link.step(0.1 + n * h, h)
    first = [x.copy() for x in link.interface_kinematics()] + [link.qf.copy()]
    link.set_interface_forces(np.zeros(4))
    link.step(0.105, h)
    link.set_state(saved)
    saved["qf"][:] = 1.0           # the link must not share memory with a saved state
    for n in range(5):
        link.step(0.1 + n * h, h)
    again = list(link.interface_kinematics()) + [link.qf]
    for x, y in zip(first, again):
        assert np.array_equal(x, y)


def _glued_crank_slider(coupler, steps, h=1e-3):
    parts = {"crank": crank_slider("crank"), "coupler": coupler, "slider": crank_slider("slider")}
    rows = parts["crank"].row_coefficients
    return march(parts, [penalized_joint("A", ("crank", "A"), ("coupler", "A"), rows),
                         penalized_joint("B", ("coupler", "B"), ("slider", "P"), rows)],
                 h, steps, tolerance=1e-7)


def test_glued_crank_slider_with_flexible_coupler():
    """Rigid crank and slider glued to the flexible coupler: with a 1000 times stiffer
    beam the joint forces approach the rigid monolithic ones; the steel coupler's
    flexibility shows as a difference of about 2 % of the peak over 0.4 s."""
    h, steps = 1e-3, 400
    reference, _ = crank_slider_reactions(steps, h)
    peak = np.max(np.abs(reference))
    stiff = _glued_crank_slider(
        FlexibleLink(**{**STEEL, "young": 210e12}, x=6.0, stiffness_damping=1e-4), steps)
    steel = _glued_crank_slider(FlexibleLink(**STEEL, x=6.0), steps)
    stiff_error = np.max(np.abs(stiff[0] - reference)) / peak
    steel_error = np.max(np.abs(steel[0] - reference)) / peak
    assert stiff_error < 1e-3                      # measured 4.5e-4
    assert 5 * stiff_error < steel_error < 0.05    # measured 2.2e-2
    assert np.mean(stiff[1]) < 6
