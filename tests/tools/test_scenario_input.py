"""A scenario's bad input (dsim run --scenario): one line each, exit 2, before anything
runs (no results file), the closest names offered where a name is unknown."""
import json

import pytest

from tests.support.runs import run_cli
from tests.support.scenarios import offset_scenes


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    return offset_scenes(tmp_path_factory.mktemp("scenario_input"))


def _event(**fields) -> str:
    event = {"time": 0.5, "model": "slave uno", "variable": "realIn", "action": "override",
             "value": 1.0}
    event.update(fields)
    return json.dumps({"events": [event]})


CASES = {
    "unknown component": (_event(model="slave un"),
                          "the scene has no component 'slave un' (closest: slave uno)"),
    "unknown variable": (_event(variable="realInn"),
                         "component 'slave uno' has no variable 'realInn' (closest: realIn,"),
    "constant": (_event(variable="version"),
                 "'slave uno.version' is a constant: FMI lets no master change it"),
    "fixed parameter": (_event(variable="intStep", value=3),
                        "'slave uno.intStep' is a fixed parameter: FMI lets a master change "
                        "it only before the run starts"),
    "after the stop time": (_event(time=1.2),
                            "t = 1.2 s is at or after the stop time 1.1 s"),
    "fraction for an Integer": (_event(variable="intIn", value=1.5),
                                "'slave uno.intIn' is Integer: 1.5 is not an integer"),
    "text for a Real": (_event(value="1.0"), "'slave uno.realIn' is Real: '1.0' is not a "
                                             "number"),
    "bias of a Boolean": (_event(variable="flag", action="bias", value=True),
                          "a bias adds to a number"),
    "unknown action": (_event(action="ramp"), "unknown action 'ramp' (the actions are "
                                              "override, bias, reset)"),
    "type the file declares": (_event(variable="intIn", type="real", value=2),
                               "'slave uno.intIn' is Integer, the file says real"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_event_is_one_line_and_nothing_runs(capsys, tmp_path, scenes, case):
    text, expected = CASES[case]
    scenario = tmp_path / "s.json"
    scenario.write_text(text)
    out = tmp_path / "out.csv"
    code, lines = run_cli(capsys, scenes["single"], "--scenario", scenario, "--out", out)
    assert code == 2 and len(lines) == 1, lines
    assert f"{scenario}: event 1: " in lines[0] and expected in lines[0], lines[0]
    assert not out.exists()


@pytest.mark.parametrize("suffix, text, said", [
    (".json", '{"events": [\n  {"time": 0.5,\n   "value": }\n]}', "line 3: malformed JSON"),
    (".yml", "events:\n  - time: 0.5\n     value: 1\n", "line 3: malformed YAML"),
    (".xml", "<Scenario>\n<action t='1'>\n<variable id='a::b'><real value='1'/>\n"
             "</action></Scenario>", "line 4: malformed XML")])
def test_a_malformed_file_names_its_line(capsys, tmp_path, scenes, suffix, text, said):
    scenario = tmp_path / f"s{suffix}"
    scenario.write_text(text)
    code, lines = run_cli(capsys, scenes["single"], "--scenario", scenario,
                          "--out", tmp_path / "o.csv")
    assert code == 2 and len(lines) == 1 and f"{scenario} {said}" in lines[0], lines


def test_every_problem_of_a_file_at_once(capsys, tmp_path, scenes):
    scenario = tmp_path / "s.json"
    scenario.write_text(json.dumps({"defaults": {"model": "slave uno", "action": "override"},
                                    "events": [{"time": 0.1, "variable": "nope", "value": 1},
                                               {"time": 0.2, "variable": "intStep",
                                                "value": 1},
                                               {"time": 0.3, "variable": "realIn",
                                                "value": 2.0}]}))
    code, lines = run_cli(capsys, scenes["single"], "--scenario", scenario,
                          "--out", tmp_path / "o.csv")
    assert code == 2 and len(lines) == 2
    assert "event 1:" in lines[0] and "event 2:" in lines[1]


def test_glued_scene_refusals(capsys, tmp_path, built):
    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    for fields, expected in (
            ({"model": "left", "variable": "P.f_x"}, "is a glued port's force: the joint sets "
                                                     "it every step"),
            ({"model": "j1", "variable": "omega"}, "joint 'j1' is a flexible joint on the "
                                                   "displacement measure: it has no law "
                                                   "coefficient 'omega'")):
        scenario = tmp_path / "s.json"
        scenario.write_text(json.dumps({"events": [{"time": 1.0, "action": "override",
                                                    "value": 1.0, **fields}]}))
        code, lines = run_cli(capsys, scene, "--scenario", scenario, "--stop", "2",
                              "--out", tmp_path / "o.csv")
        assert code == 2 and len(lines) == 1 and expected in lines[0], lines


def test_an_output_under_step_auto_is_refused_in_one_line(capsys, tmp_path, scenes):
    # the steps --step auto takes between its output points pass the FMUs' own outputs
    scenario = tmp_path / "s.json"
    scenario.write_text(_event(variable="realOut"))
    code, lines = run_cli(capsys, scenes["single"], "--scenario", scenario, "--step", "auto",
                          "--out", tmp_path / "o.csv")
    assert code == 2 and len(lines) == 1 and "is an output: with --step auto" in lines[0]
