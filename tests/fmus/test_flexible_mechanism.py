"""The monolithic crank slider with a flexible coupler (fmus/flexible_link/mechanism.py):
the reference of crank_slider_flexible.  Checks of the model itself; the glued scene
against it is in tests/fmus/test_linkage_scenes.py."""
from __future__ import annotations

import numpy as np
import pytest

from dsim.fmus.flexible_link.mechanism import crank_slider_flexible
from dsim.fmus.linkage.scenes import crank_slider

H, STEPS = 1e-3, 300


def _run(model, steps=STEPS):
    """Joint A force (N), coupler angular velocity (rad/s), slider x (m) per step."""
    model.initialize(0.0)
    rows = [(0.0, 0.0, 0.0, model.rigid.q[1, 0])]
    for n in range(steps):
        model.step(n * H, H)
        rows.append((*model.forces[0], model.links["coupler"].omega, model.rigid.q[1, 0]))
    return np.array(rows)


@pytest.fixture(scope="module")
def rigid_reference():
    whole = crank_slider("whole")
    whole.initialize(0.0)
    rows = [(0.0, 0.0, 0.0, whole.q[2, 0])]
    for n in range(STEPS):
        whole.step(n * H, H)
        r = whole.reactions()
        rows.append((r["A.f_x"], r["A.f_y"], whole.v[1, 2], whole.q[2, 0]))
    return np.array(rows)


def _differences(rows, reference):
    peak = np.max(np.hypot(reference[:, 0], reference[:, 1]))
    return (np.max(np.hypot(*(rows[:, :2] - reference[:, :2]).T)) / peak,
            np.max(np.abs(rows[:, 2] - reference[:, 2])),
            np.max(np.abs(rows[:, 3] - reference[:, 3])))


def test_jacobian_is_exact():
    """Newton's matrix against central differences of the residual, mid-run (the
    coupler rotating and bent, joint forces of kN)."""
    model = crank_slider_flexible()
    model.initialize(0.0)
    for n in range(150):
        model.step(n * H, H)
    preds = model._predictors(H)
    rng = np.random.default_rng(1)
    x = model._unknowns() * (1.0 + 1e-3 * rng.standard_normal(model.size))
    _, jac, *_ = model._system(x, preds, model.time + H, H)
    numeric = np.zeros_like(jac)
    for i in range(model.size):
        e = np.zeros(model.size)
        e[i] = 1e-4 * max(1.0, abs(x[i]))
        numeric[:, i] = (model._system(x + e, preds, model.time + H, H)[0]
                         - model._system(x - e, preds, model.time + H, H)[0]) / (2 * e[i])
    assert np.max(np.abs(jac - numeric)) < 1e-5 * np.max(np.abs(jac))
    assert model.newton_iterations <= 3        # quadratic convergence: 2 per step


def test_stiff_coupler_reproduces_the_rigid_linkage(rigid_reference):
    """With E x 1e4 and E x 1e5 the flexible model approaches the rigid monolithic
    crank slider (one Linkage), the slider position error falling as 1/E (static
    deflection); the steel coupler differs by its flexibility (4 % of the peak force over 0.3 s)."""
    light = dict(stiffness_damping=1e-5)      # damps the start-up vibration of a stiff beam
    stiff = _differences(_run(crank_slider_flexible(coupler=dict(young=210e13, **light))),
                         rigid_reference)
    stiffer = _differences(_run(crank_slider_flexible(coupler=dict(young=210e14, **light))),
                           rigid_reference)
    steel = _differences(_run(crank_slider_flexible()), rigid_reference)
    # measured 3.1e-4 of the peak force, 6.6e-8 rad/s, 8.0e-10 m
    assert stiff[0] < 1e-3 and stiff[1] < 3e-7 and stiff[2] < 3e-9
    assert stiffer[0] < stiff[0] / 2 and stiffer[1] < stiff[1] / 5  # measured 9.3e-5, 6.7e-9
    assert stiffer[2] == pytest.approx(stiff[2] / 10, rel=0.05)        # 1 / E
    assert 1e-2 < steel[0] < 0.1                                      # measured 4.2e-2


def test_steel_coupler_keeps_joints_and_mean_axis():
    """Joints closed to the stabilised rows' level, elastic field free of rigid motion
    (the projected load keeps the mean-axis conditions to round-off), the coupler
    bends visibly."""
    model = crank_slider_flexible()
    model.initialize(0.0)
    for n in range(STEPS):
        model.step(n * H, H)
        assert model.joint_violation() < 1e-7                          # m
    out = model.links["coupler"].outputs()
    assert out["mean_axis_violation"] < 1e-9
    assert out["deflection"] > 1e-5                                    # m
