"""A scenario on a glued scene (docs/scenarios.md): a force applied at 2 s to
spring_mass_nonlinear, through the input right.P.f_x that no joint or connection
feeds, against a reference made by editing the scene.

The comparison that holds: the scene edited so that it rests until the event (its one
load, right.F0[2], set to 0: every value stays exactly 0), then

- the scenario run overrides right.P.f_x = 5 N at 2 s (port P sits on mass 1 of right);
- the reference is the same rest scene with the load on mass 1 from its start instead
  (right.F0[1] = 5: the same force on the same mass), run from 0.

The system is autonomous, so the scenario's motion from 2 s is the reference's from 0,
up to how each starts its load: SpringMass integrates by the trapezoidal rule, which
sees the load at both ends of a step.  The reference's load is there at its start (its
initialization computes the start accelerations with it); the scenario's enters at the
communication point 2 s, after the accelerations there were computed without it, so its
first step carries half the load on average: the scenario lags the reference by half a
step.  Against the reference shifted by half a step (the mean of two consecutive rows)
the positions agree to O(h^2), which the test measures at two steps (a run whose
event acts a step late or early, or on another mass, or with another value, agrees
only to O(h) or not at all).
"""
import json

import numpy as np

import dsim

#: the scene's one load switched off: it rests at 0 until the event
AT_REST = {"right.F0[2]": 0}
POSITIONS = ("left.x[1]", "right.x[1]", "right.x[2]")


def _lag(scene, scenario, step):
    """Per position column, the largest difference (relative to the reference's peak)
    between the scenario run from 2 s and the reference shifted by half a step; and the
    scenario run."""
    run = dsim.simulate(scene, stop=3.5, step=step, parameters=AT_REST, scenario=scenario)
    reference = dsim.simulate(scene, stop=1.5, step=step,
                              parameters={**AT_REST, "right.F0[1]": 5.0})
    event = round(2.0 / step)
    worst = {}
    for column in POSITIONS:
        after = run[column][event:]
        shifted = (reference[column][1:] + reference[column][:-1]) / 2
        worst[column] = np.abs(after[1:] - shifted).max() / np.abs(reference[column]).max()
    return worst, run, event


def test_a_force_override_at_2_s_matches_the_scene_edited_to_carry_it(tmp_path, built):
    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    scenario = tmp_path / "force.json"
    scenario.write_text(json.dumps({"events": [{"time": 2.0, "model": "right",
                                                "variable": "P.f_x", "action": "override",
                                                "value": 5.0}]}))
    coarse, run, event = _lag(scene, scenario, 0.01)
    # nothing moves before the event's point, and the row after it is the first to move
    for column in POSITIONS + ("j1.f_x",):
        assert not np.any(run[column][:event + 1]), column
    assert np.all(run["right.x[1]"][event + 1:] != 0)
    # measured 4.5e-5 .. 7.3e-5 of the peak at h = 0.01 s
    assert max(coarse.values()) < 2e-4, coarse
    fine, _, _ = _lag(scene, scenario, 0.005)
    # halving the step divides the difference by 4 (measured 3.9 to 3.95): O(h^2)
    for column in POSITIONS:
        assert 3.0 < coarse[column] / fine[column] < 5.0, (column, coarse, fine)
    applied = run.statistics["scenario"]["applied"]
    assert applied == [{"time": 2.0, "event_time": 2.0, "target": "right.P.f_x",
                        "kind": "set", "action": "override", "old": 0.0, "new": 5.0}]
