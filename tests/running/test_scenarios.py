"""Scenario files in runs (dsim run --scenario; docs/scenarios.md): libcosim's scenario1
on a slave that behaves like libcosim's test slave gives libcosim's expected numbers at
every step, ECOS's XML fires as ECOS's rule says, connected inputs, outputs that feed
connections and tunable parameters change as the statistics say, on the in-process and
the isolated backend, and a run without a scenario (or with one that changes nothing)
writes the same bytes."""
import json

import numpy as np
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.scenarios import SCENARIO1_JSON, SCENARIO1_YAML, offset_scenes


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    return offset_scenes(tmp_path_factory.mktemp("scenarios"))


def _scenario(folder, name, text):
    path = folder / name
    path.write_text(text)
    return path


def _rows(result, column):
    """A column's values at t = 0.1, 0.2, ..., the samples libcosim's test reads (from
    step 1 on: the start row is not among them)."""
    return result[column][1:]


# libcosim's test (test/cpp/scenario_parser_unittest.cpp), start 0, stop 1.1, step 0.1:
# the samples at t = 0.1 .. 1.1 it expects of its mock slave's realIn, realOut, intIn
# and intOut
LIBCOSIM_REAL_IN = [0.0, 0.0, 0.0, 0.0, 0.0, 2.001, 2.001, 2.001, 2.001, 2.001, 1.0]
LIBCOSIM_REAL_OUT = [1.234, 1.234, -1.0, 1.234, 1.234, 3.235, 3.235, 3.235, 3.235, 3.235,
                     2.234]
LIBCOSIM_INT_IN = [0, 0, 0, 0, 0, 0, 0, 2, 2, 2, 1]
LIBCOSIM_INT_OUT = [2, 2, 2, 2, 2, 2, 2, 4, 5, 5, 3]


@pytest.mark.parametrize("suffix", ["json", "yml"])
def test_libcosim_scenario1_gives_libcosims_numbers_on_a_slave_like_its_mock(
        scenes, tmp_path, suffix):
    # libcosim's mock slave declares realIn start 1.0 and intIn start 1, but holds 0 in
    # both until a master writes them; the scenario's first input event (realIn bias at
    # 0.5) makes libcosim write the input from then on, as the declared start plus the
    # bias (1.0 + 1.001 = 2.001), and its end (1.0) takes the bias back to the declared
    # start (1.0, intIn 1).  offset.c compiled with MOCK_INPUTS_ZERO does the same (the
    # only way to get these numbers: an FMU whose declared start disagrees with what it
    # holds), and dsim writes an input no connection feeds only when an event changes
    # it, from its declared start: libcosim's numbers at every step.
    text = SCENARIO1_JSON if suffix == "json" else SCENARIO1_YAML
    result = dsim.simulate(scenes["mock"], scenario=_scenario(tmp_path, f"s.{suffix}", text))
    assert result.status == "completed" and result.steps == 11
    np.testing.assert_allclose(_rows(result, "slave uno.realInEcho"), LIBCOSIM_REAL_IN,
                               rtol=1e-12, atol=0)
    np.testing.assert_allclose(_rows(result, "slave uno.realOut"), LIBCOSIM_REAL_OUT,
                               rtol=1e-12, atol=0)
    assert _rows(result, "slave uno.intInEcho").tolist() == LIBCOSIM_INT_IN
    assert _rows(result, "slave uno.intOut").tolist() == LIBCOSIM_INT_OUT


def test_scenario1_on_a_consistent_slave_gives_the_numbers_derived_by_hand(scenes, tmp_path):
    # The same events on offset.c as FMI means it: its inputs hold their declared starts
    # (realIn 1.0, intIn 1) from the start.  Each event acts on the step that starts at
    # the first communication point at or after its time, and shows in the next row:
    #   realOut override -1 at 0.2     -> realOut -1 at 0.3 (an output: modified as read)
    #   realOut reset at 0.3           -> realOut 1.0 + 1.234 = 2.234 again at 0.4
    #   realIn bias 1.001 at 0.5       -> realIn 1.0 + 1.001 = 2.001 from 0.6, realOut 3.235
    #   intIn override 2 at 0.65 (0.7) -> intIn 2 from 0.8, intOut 2 + 2 = 4
    #   intOut override 5 at 0.8       -> intOut 5 from 0.9
    #   end 1.0: every change back     -> realIn 1.0, realOut 2.234, intIn 1, intOut 3 at 1.1
    # Where libcosim's mock has been written (from 0.6 on) these are libcosim's numbers;
    # before, the consistent slave holds its starts where the mock holds 0.
    result = dsim.simulate(scenes["single"], scenario=_scenario(tmp_path, "s.json",
                                                                SCENARIO1_JSON))
    np.testing.assert_allclose(
        _rows(result, "slave uno.realInEcho"),
        [1.0, 1.0, 1.0, 1.0, 1.0, 2.001, 2.001, 2.001, 2.001, 2.001, 1.0], rtol=1e-12)
    np.testing.assert_allclose(
        _rows(result, "slave uno.realOut"),
        [2.234, 2.234, -1.0, 2.234, 2.234, 3.235, 3.235, 3.235, 3.235, 3.235, 2.234],
        rtol=1e-12)
    assert _rows(result, "slave uno.intInEcho").tolist() == [1, 1, 1, 1, 1, 1, 1, 2, 2, 2, 1]
    assert _rows(result, "slave uno.intOut").tolist() == [3, 3, 3, 3, 3, 3, 3, 4, 5, 5, 3]
    # the statistics list every change: when it took effect, the target, old and new
    applied = result.statistics["scenario"]["applied"]
    assert [(round(a["time"], 9), a["target"], a["action"], a["old"], a["new"])
            for a in applied] == [
        (0.2, "slave uno.realOut", "override", 2.234, -1.0),
        (0.3, "slave uno.realOut", "reset", -1.0, 2.234),
        (0.5, "slave uno.realIn", "bias", 1.0, 2.001),
        (0.7, "slave uno.intIn", "override", 1, 2),
        (0.8, "slave uno.intOut", "override", 4, 5),
        (1.0, "slave uno.realIn", "end", 2.001, 1.0),
        (1.0, "slave uno.intIn", "end", 2, 1),
        (1.0, "slave uno.intOut", "end", 5, 4)]


def test_ecos_xml_fires_by_ecos_rule_on_every_type(scenes, tmp_path):
    # ECOS invokes an action at the first point t with t > its time, or within eps of
    # it: at 0.5 exactly (5 * 0.1 == 0.5) without eps it fires at 0.6, with eps 0.01 at
    # 0.5; every action is an override, shown in the row after it fires
    path = _scenario(tmp_path, "s.xml", """<?xml version="1.0" encoding="UTF-8"?>
<ecos:Scenario xmlns:ecos="http://github.com/Ecos-platform/libecos/resources/schema/ScenarioConfig">
  <ecos:action t="0.2" eps="0.05">
    <ecos:variable id="slave uno::realIn"><ecos:real value="5.0"/></ecos:variable>
  </ecos:action>
  <ecos:action t="0.5">
    <ecos:variable id="slave uno::intIn"><ecos:integer value="7"/></ecos:variable>
  </ecos:action>
  <ecos:action t="0.5" eps="0.01">
    <ecos:variable id="slave uno::flag"><ecos:boolean value="true"/></ecos:variable>
  </ecos:action>
  <ecos:action t="0.75">
    <ecos:variable id="slave uno::offset"><ecos:real value="10"/></ecos:variable>
    <ecos:variable id="slave uno::label"><ecos:string value="hello"/></ecos:variable>
  </ecos:action>
</ecos:Scenario>""")
    result = dsim.simulate(scenes["single"], scenario=path)
    assert _rows(result, "slave uno.realInEcho").tolist() == [1.0, 1.0] + [5.0] * 9
    # realOut = realIn + offset: the tunable offset set at 0.8 shows at 0.9
    np.testing.assert_allclose(_rows(result, "slave uno.realOut"),
                               [2.234, 2.234] + [6.234] * 6 + [15.0] * 3, rtol=1e-12)
    assert _rows(result, "slave uno.intInEcho").tolist() == [1] * 6 + [7] * 5
    assert _rows(result, "slave uno.flagOut").tolist() == [0] * 5 + [1] * 6
    assert list(_rows(result, "slave uno.labelOut")) == [""] * 8 + ["hello"] * 3


def test_connected_inputs_outputs_and_tunable_parameters_change_where_the_run_moves_them(
        scenes, tmp_path):
    # a.realOut -> b.realIn and a.intOut -> b.intIn; a.realIn is not connected (1.0), so
    # a.realOut is 2.234 and b.realOut 3.468 until the events:
    #   0.2 override b.realIn 10 (connected): b steps with 10 from 0.2 -> b.realInEcho 10
    #       at 0.3
    #   0.3 a.offset 2 (tunable, set):           a.realOut 1 + 2 = 3 at 0.4
    #   0.4 reset b.realIn: the connection's value again, a.realOut at 0.4 = 3 -> b 3 at 0.5
    #   0.5 bias a.realOut +100 (an output): read after the step from 0.5 -> 103 at 0.6,
    #       and what b receives for its step from 0.6 -> b.realInEcho 103 at 0.7
    #   0.6 override b.intIn 7 (connected Integer) -> b.intInEcho 7 at 0.7, b.intOut 9
    #   end 0.8: every change back: a's offset 1.234, a.realOut as read (2.234 at 0.9);
    #       b's step from 0.8 takes a.realOut as recorded at 0.8 (103) -> 103 at 0.9
    path = _scenario(tmp_path, "chain.yaml", """
events:
  - {time: 0.2, model: b, variable: realIn, action: override, value: 10}
  - {time: 0.3, model: a, variable: offset, action: override, value: 2.0}
  - {time: 0.4, model: b, variable: realIn, action: reset}
  - {time: 0.5, model: a, variable: realOut, action: bias, value: 100}
  - {time: 0.6, model: b, variable: intIn, action: override, value: 7}
end: 0.8
""")
    result = dsim.simulate(scenes["chain"], scenario=path)
    t = result["time"]
    assert len(t) == 11
    np.testing.assert_allclose(result["a.realOut"], [2.234] * 4 + [3.0] * 2 + [103.0] * 3
                               + [2.234] * 2, rtol=1e-12)
    # (at the start b echoes 0: offset.c computes a.realOut only when initialization
    # ends, after the connection carried a's value into b)
    np.testing.assert_allclose(result["b.realInEcho"], [0.0] + [2.234] * 2 + [10.0] * 2
                               + [3.0] * 2 + [103.0] * 3 + [2.234], rtol=1e-12)
    assert result["b.intInEcho"].tolist() == [0] + [3] * 6 + [7] * 2 + [3] * 2
    assert result["b.intOut"].tolist() == [2] + [5] * 6 + [9] * 2 + [5] * 2
    applied = result.statistics["scenario"]["applied"]
    assert [(a["target"], a["kind"], a["action"], a["old"], a["new"]) for a in applied] == [
        ("b.realIn", "input", "override", 2.234, 10.0),
        ("a.offset", "set", "override", 1.234, 2.0),
        ("b.realIn", "input", "reset", 10.0, 3.0),
        ("a.realOut", "output", "bias", 3.0, 103.0),
        ("b.intIn", "input", "override", 3, 7),
        ("a.offset", "set", "end", 2.0, 1.234),
        ("a.realOut", "output", "end", 103.0, 3.0),
        ("b.intIn", "input", "end", 7, 3)]


def test_step_auto_applies_input_and_parameter_events_at_its_output_points(scenes, tmp_path):
    # --step auto chooses its steps between the output points (every 0.1 s here); an
    # event takes effect at the output point at or after its time, as with a fixed step
    path = _scenario(tmp_path, "s.json", json.dumps({"defaults": {"model": "slave uno"},
                                                     "events": [
        {"time": 0.45, "variable": "realIn", "action": "override", "value": 3.0},
        {"time": 0.7, "variable": "offset", "action": "override", "value": 0.5}]}))
    result = dsim.simulate(scenes["single"], scenario=path, step="auto", output_interval=0.1)
    np.testing.assert_allclose(result["slave uno.realOut"],
                               [2.234] * 6 + [4.234] * 2 + [3.5] * 4, rtol=1e-12)


def test_the_isolated_backend_gives_the_in_process_numbers(scenes, tmp_path, ray_local):
    scenario = _scenario(tmp_path, "s.json", SCENARIO1_JSON)
    here = dsim.simulate(scenes["chain"], scenario=_scenario(
        tmp_path, "c.json", json.dumps({"events": [
            {"time": 0.2, "model": "b", "variable": "realIn", "action": "bias", "value": 1},
            {"time": 0.3, "model": "a", "variable": "offset", "action": "override",
             "value": 5},
            {"time": 0.5, "model": "a", "variable": "realOut", "action": "override",
             "value": -4}]})))
    there = dsim.simulate(scenes["chain"], scenario=tmp_path / "c.json", backend="isolated")
    for column in ("a.realOut", "b.realInEcho", "b.realOut"):
        assert np.array_equal(here[column], there[column]), column
    assert here.statistics["scenario"]["applied"] == there.statistics["scenario"]["applied"]
    mock = dsim.simulate(scenes["mock"], scenario=scenario, backend="isolated")
    assert _rows(mock, "slave uno.intOut").tolist() == LIBCOSIM_INT_OUT


def test_a_scenario_that_changes_nothing_writes_the_bytes_of_a_run_without_one(
        scenes, tmp_path, built):
    # the scenario's path through a run (its transfer, the step wrapper) adds no
    # round-off: events that override with the unmodified value, and none at all
    nothing = _scenario(tmp_path, "nothing.json", '{"events": []}')
    same = _scenario(tmp_path, "same.json", json.dumps({"events": [
        {"time": 0.3, "model": "b", "variable": "realIn", "action": "bias", "value": 0.0},
        {"time": 0.4, "model": "a", "variable": "offset", "action": "override",
         "value": 1.234}]}))
    for scene, scenario, stop in ((scenes["chain"], same, "1"),
                                  (built["ssp"] / "spring_mass_nonlinear.ssp", nothing, "1")):
        plain, with_scenario = tmp_path / "plain.csv", tmp_path / "with.csv"
        assert main(["run", str(scene), "--stop", stop, "--out", str(plain), "--quiet"]) == 0
        assert main(["run", str(scene), "--stop", stop, "--out", str(with_scenario),
                     "--scenario", str(scenario), "--quiet"]) == 0
        assert plain.read_bytes() == with_scenario.read_bytes(), scene
        statistics = json.loads(with_scenario.with_suffix(".stats.json").read_text())
        assert "scenario" not in json.loads(plain.with_suffix(".stats.json").read_text())
        assert len(statistics["scenario"]["applied"]) == (2 if scenario == same else 0)


def test_dsim_info_lists_each_event_where_it_takes_effect(scenes, tmp_path, capsys):
    path = _scenario(tmp_path, "s.yml", SCENARIO1_YAML)
    assert main(["info", str(scenes["single"]), "--scenario", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    listed = lines[lines.index(next(line for line in lines if line.startswith("scenario "))):]
    assert listed == [
        f"scenario {path} (libcosim's format): 5 events",
        "  t = 0.2 s -> at t = 0.2 s (point 2): slave uno.realOut (Real output): override -1.0",
        "  t = 0.3 s -> at t = 0.3 s (point 3): slave uno.realOut (Real output): reset",
        "  t = 0.5 s -> at t = 0.5 s (point 5): slave uno.realIn (Real set, input): bias 1.001",
        "  t = 0.65 s -> at t = 0.7 s (point 7): slave uno.intIn (Integer set, input): "
        "override 2",
        "  t = 0.8 s -> at t = 0.8 s (point 8): slave uno.intOut (Integer output): override 5",
        "  end t = 1 s: every modification taken back at t = 1 s (point 10)"]


def test_every_point_of_a_sweep_runs_the_scenario(scenes, tmp_path, capsys):
    path = _scenario(tmp_path, "s.json", json.dumps({"events": [
        {"time": 0.3, "model": "a", "variable": "realIn", "action": "override",
         "value": 2.0}]}))
    out = tmp_path / "sweep"
    assert main(["sweep", str(scenes["chain"]), "--step", "0.1,0.05", "--scenario", str(path),
                 "--out", str(out)]) == 0
    for point in ("point_001", "point_002"):
        applied = json.loads((out / f"{point}.stats.json").read_text())["scenario"]["applied"]
        assert [(a["target"], a["new"]) for a in applied] == [("a.realIn", 2.0)]
        # a.realOut = a.realIn + 1.234: 3.234 from the step after 0.3 s on
        rows = (out / f"{point}.csv").read_text().splitlines()
        assert rows[-1].split(",")[1] == "3.234"
