"""A scenario that changes a joint's law during a run (``j.k0``, docs/scenarios.md):
against the monolithic twin with the same changes, resumed from a checkpoint, on the
penalized measure, and refused in one line where it cannot apply."""
import json

import numpy as np
import pytest

import dsim
from dsim.master.errors import InputError
from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain

#: the testbed's joint j (examples/testbed.py: k0 = 100 N/m, c0 = 14.14 N.s/m) made four
#: times as stiff at 1 s, its damping raised by 10 N.s/m at 2 s
EVENTS = [{"time": 1.0, "model": "j", "variable": "k0", "action": "override", "value": 400.0},
          {"time": 2.0, "model": "j", "variable": "c0", "action": "bias", "value": 10.0}]
POSITIONS = ("left.x[1]", "right.x[1]", "right.x[2]")


def _scenario(tmp_path, events, name="law.json"):
    path = tmp_path / name
    path.write_text(json.dumps({"events": events}))
    return path


def _testbed(tmp_path, stop, step=0.01):
    from examples.testbed import Testbed, write_scene

    bed = Testbed(x0=0.01)
    return bed, write_scene(bed, tmp_path, "testbed", step, stop, tolerance=1e-12)


def _twin(bed, step, stop, laws):
    """The testbed as one chain (m1 - joint spring and damper - m2 - m3), its joint's
    spring and damper changed before the steps ``laws`` names (step -> (k0, c0)): the
    positions, one row per step."""
    def chain(k0, c0):
        params = ChainParameters(n=3)
        params.m[:3] = bed.m1, bed.m2, bed.m3
        params.k[:2], params.c[:2] = (k0, bed.k), (c0, bed.c)
        params.k_ground[0], params.x0[0], params.F0[2] = bed.kg, bed.x0, bed.F0
        made = SpringMassChain(params)
        made.initialize(0.0)
        return made

    one = chain(bed.k0, bed.c0)
    rows = [one.x[:3].copy()]
    for n in range(round(stop / step)):
        if n in laws:
            state, one = one.get_state(), chain(*laws[n])
            one.set_state(state)
        one.step(n * step, step)
        rows.append(one.x[:3].copy())
    return np.array(rows)


def test_a_joint_made_stiffer_and_more_damped_mid_run_is_the_twin_changed_the_same(
        built, tmp_path):
    bed, scene = _testbed(tmp_path, 3.0)
    result = dsim.simulate(scene, scenario=_scenario(tmp_path, EVENTS), handle_signals=False)
    assert result.status == "completed", result.message
    twin = _twin(bed, 0.01, 3.0, {100: (400.0, bed.c0), 200: (400.0, bed.c0 + 10.0)})
    for k, name in enumerate(POSITIONS):  # measured: 7e-16 of the peak
        assert np.max(np.abs(result[name] - twin[:, k])) <= 1e-9 * np.max(np.abs(twin[:, k]))
    unchanged = dsim.simulate(scene, handle_signals=False)  # the change shows
    assert np.max(np.abs(unchanged["left.x[1]"] - result["left.x[1]"])) > 1e-3
    assert result.statistics["scenario"]["applied"] == [
        {"time": 1.0, "event_time": 1.0, "target": "j.k0", "kind": "joint",
         "action": "override", "old": 100.0, "new": 400.0},
        {"time": 2.0, "event_time": 2.0, "target": "j.c0", "kind": "joint",
         "action": "bias", "old": bed.c0, "new": bed.c0 + 10.0}]


def test_dsim_info_lists_a_joint_law_event(built, tmp_path, capsys):
    from dsim.master.tools.cli import main

    _, scene = _testbed(tmp_path, 3.0)
    assert main(["info", str(scene), "--scenario", str(_scenario(tmp_path, EVENTS))]) == 0
    said = capsys.readouterr().out
    assert "t = 1 s -> at t = 1 s (point 100): j.k0 (joint law): override 400.0" in said
    assert "t = 2 s -> at t = 2 s (point 200): j.c0 (joint law): bias 10.0" in said


def test_a_run_resumed_after_a_law_change_goes_on_with_the_changed_law(built, tmp_path):
    """Killed with SIGKILL after the changes (the first checkpoint at 5 s), resumed: the
    bytes of the run never stopped (a checkpoint keeps the joints' state, the scenario
    sets its laws again)."""
    from tests.support.checkpoints import killed_and_resumed, timeless

    _, scene = _testbed(tmp_path, 60.0)
    (reference, expected), (out, statistics) = killed_and_resumed(
        scene, tmp_path, 60.0, 5.0, both=("--scenario", _scenario(tmp_path, EVENTS)))
    assert out == reference
    assert timeless(statistics) == timeless(expected)


def test_the_penalized_measures_coefficients_set_by_a_scenario_weigh_as_set_for_the_run(
        built, tmp_path):
    """four_bar_singular_penalized's joints given xi = 0.7, omega = 500 rad/s by events
    at 0 s: the bits of the run given them by --set (the measure's weights are what the
    penalized joint's Newton solves with; the start rows hold no weighted term).  The
    same at 0.2 s: every row before it the unchanged run's, the later ones not."""
    scene = built["ssp"] / "four_bar_singular_penalized.ssp"
    names = [j.name for j in dsim.load_scene(scene).joints]
    given = {f"{n}.{v}": x for n in names for v, x in (("xi", 0.7), ("omega", 500.0))}

    def events(time):
        return [{"time": time, "model": name.split(".")[0], "variable": name.split(".")[1],
                 "action": "override", "value": value} for name, value in given.items()]

    at_start = dsim.simulate(scene, stop=0.6, handle_signals=False,
                             scenario=_scenario(tmp_path, events(0.0), "start.json"))
    for_the_run = dsim.simulate(scene, stop=0.6, parameters=given, handle_signals=False)
    plain = dsim.simulate(scene, stop=0.6, handle_signals=False)
    later = dsim.simulate(scene, stop=0.6, handle_signals=False,
                          scenario=_scenario(tmp_path, events(0.2), "later.json"))
    assert at_start.status == for_the_run.status == later.status == "completed"
    columns = [n for n in plain.signals if n != "time"]
    for name in columns:
        assert np.array_equal(at_start[name], for_the_run[name]), name
        assert np.array_equal(later[name][:21], plain[name][:21]), name  # to 0.2 s
    assert max(np.max(np.abs(later[n][21:] - plain[n][21:])) for n in columns) > 1e-6


@pytest.mark.parametrize("event, said", [
    (dict(model="j", variable="xi", value=1.0),
     "joint 'j' is a flexible joint on the displacement measure: it has no law coefficient "
     "'xi' (a scenario can change k0, k1, c0, c1)"),
    (dict(model="j", variable="k0", value=-1.0),
     "'j.k0' would be -1: a k0 below zero is not physical"),
    (dict(model="j", variable="c0", value=-20.0, action="bias"),
     "'j.c0' would be -5.86: a c0 below zero is not physical"),
    (dict(model="j", variable="k0", value="stiff"),
     "'j.k0' is a joint law coefficient (Real): 'stiff' is not a number"),
    (dict(model="jj", variable="k0", value=1.0), "the scene has no component 'jj' (closest: j"),
])
def test_a_joint_law_event_that_cannot_apply_is_one_line(built, tmp_path, event, said):
    _, scene = _testbed(tmp_path, 3.0)
    path = _scenario(tmp_path, [{"time": 1.0, "action": "override", **event}])
    with pytest.raises(InputError) as error:
        dsim.simulate(scene, scenario=path, handle_signals=False)
    assert said in str(error.value)


def test_a_joint_law_event_on_the_ray_backend_gives_the_in_process_numbers(
        built, tmp_path, ray_local):
    """The joints live in the master, wherever the FMUs run: the same bits."""
    _, scene = _testbed(tmp_path, 3.0)
    scenario = _scenario(tmp_path, EVENTS)
    here = dsim.simulate(scene, scenario=scenario, handle_signals=False)
    there = dsim.simulate(scene, scenario=scenario, backend="ray", handle_signals=False)
    for name in [*POSITIONS, "j.f_x"]:
        assert np.array_equal(here[name], there[name]), name
    assert here.statistics["scenario"] == there.statistics["scenario"]
