"""Scenario files as written (master/reading/scenario_files.py): libcosim's JSON and YAML
and ECOS's XML read into the same events, and every malformed file refused in one line
that names the file and the line, the untrusted file parsed safely."""
import json

import pytest

from dsim.master.errors import InputError
from dsim.master.reading.scenario_files import read_scenario

#: one scenario in libcosim's format, as JSON and as YAML (our own content)
JSON_TEXT = """{
  "defaults": {"model": "pump", "variable": "speed", "action": "override"},
  "events": [
    {"time": 1.5, "value": 30.0},
    {"time": 2, "variable": "gain", "action": "bias", "value": -2},
    {"time": 3.25, "action": "reset"},
    {"time": 4, "model": "valve", "variable": "open", "value": true}
  ],
  "end": 5
}
"""
YAML_TEXT = """---
defaults:
  model: pump
  variable: speed
  causality: input
  type: real
  action: override
events:
  - time: 1.5
    value: 30.0
  - time: 2
    variable: gain
    action: bias
    value: -2
  - time: 3.25
    action: reset
  - time: 4
    model: valve
    variable: open
    type: boolean
    value: true
end: 5
"""


def _write(folder, name, text):
    path = folder / name
    path.write_text(text)
    return path


def _problems(path) -> list[str]:
    with pytest.raises(InputError) as caught:
        read_scenario(path)
    return caught.value.problems


def test_json_and_yaml_of_libcosim_give_the_same_events(tmp_path):
    from_json = read_scenario(_write(tmp_path, "s.json", JSON_TEXT))
    from_yaml = read_scenario(_write(tmp_path, "s.yml", YAML_TEXT))
    plain = [(e.time, e.model, e.variable, e.action, e.value) for e in from_json.events]
    assert plain == [(1.5, "pump", "speed", "override", 30.0),
                     (2.0, "pump", "gain", "bias", -2),
                     (3.25, "pump", "speed", "reset", None),
                     (4.0, "valve", "open", "override", True)]
    assert [(e.time, e.model, e.variable, e.action, e.value)
            for e in from_yaml.events] == plain
    assert from_json.end == from_yaml.end == 5.0
    assert from_json.format == from_yaml.format == "libcosim"
    # the YAML declares types (informative in libcosim; dsim checks them against the FMU)
    assert [e.declared_type for e in from_yaml.events] == ["real", "real", "real", "boolean"]


def test_ecos_xml_gives_overrides_with_their_eps(tmp_path):
    path = _write(tmp_path, "s.xml", """<?xml version="1.0" encoding="UTF-8"?>
<ecos:Scenario xmlns:ecos="urn:example:scenario" eps="0.001">
  <ecos:action t="0.5" eps="0.05">
    <ecos:variable id="pump::speed"><ecos:real value="12.5"/></ecos:variable>
    <ecos:variable id="pump::mode"><ecos:integer value="3"/></ecos:variable>
  </ecos:action>
  <!-- a comment -->
  <ecos:action t="2">
    <ecos:variable id="valve::open"><ecos:boolean value="false"/></ecos:variable>
    <ecos:variable id="valve::name"><ecos:string value="main"/></ecos:variable>
  </ecos:action>
</ecos:Scenario>""")
    scenario = read_scenario(path)
    assert scenario.format == "ecos" and scenario.end is None
    assert [(e.time, e.model, e.variable, e.action, e.value, e.eps, e.declared_type)
            for e in scenario.events] == [
        (0.5, "pump", "speed", "override", "12.5", 0.05, "Real"),
        (0.5, "pump", "mode", "override", "3", 0.05, "Integer"),
        (2.0, "valve", "open", "override", "false", 0.001, "Boolean"),
        (2.0, "valve", "name", "override", "main", 0.001, "String")]
    assert all(e.rule == "ecos" for e in scenario.events)


def test_malformed_json_names_the_file_and_line(tmp_path):
    path = _write(tmp_path, "bad.json", '{\n  "events": [\n    {"time": 1,}\n  ]\n}\n')
    problems = _problems(path)
    assert len(problems) == 1 and f"{path} line 3: malformed JSON" in problems[0]


def test_malformed_yaml_names_the_file_and_line(tmp_path):
    path = _write(tmp_path, "bad.yml", "events:\n  - time: 1\n    value: [1, 2\n  - x\n")
    problems = _problems(path)
    assert len(problems) == 1 and f"{path} line " in problems[0] and \
        "malformed YAML" in problems[0]


def test_malformed_xml_names_the_file_and_line(tmp_path):
    path = _write(tmp_path, "bad.xml", "<Scenario>\n  <action t='1'>\n  </actio>\n</Scenario>")
    problems = _problems(path)
    assert len(problems) == 1 and f"{path} line 3: malformed XML" in problems[0]


def test_an_unknown_action_and_missing_keys_are_one_line_each(tmp_path):
    path = _write(tmp_path, "s.json", json.dumps({"events": [
        {"time": 1, "model": "m", "variable": "v", "action": "ramp", "value": 1},
        {"time": 2, "model": "m", "action": "override", "value": 1},
        {"model": "m", "variable": "v", "action": "override", "value": 1},
        {"time": 3, "model": "m", "variable": "v", "action": "bias"},
        {"time": "soon", "model": "m", "variable": "v", "action": "reset"}]}))
    problems = _problems(path)
    assert problems == [
        f"{path}: event 1: unknown action 'ramp' (the actions are override, bias, reset)",
        f"{path}: event 2: no 'variable', neither here nor in 'defaults'",
        f"{path}: event 3: no 'time'",
        f"{path}: event 4: action 'bias' needs a 'value'",
        f"{path}: event 5: 'time' is 'soon': give a number of seconds"]


def test_yaml_is_read_as_plain_data_only(tmp_path):
    # a Python object tag would run code under yaml.load: safe_load refuses it
    path = _write(tmp_path, "evil.yaml",
                  "events: !!python/object/apply:os.system ['touch " + str(tmp_path / "owned")
                  + "']\n")
    problems = _problems(path)
    assert len(problems) == 1 and "malformed YAML" in problems[0]
    assert not (tmp_path / "owned").exists()


def test_xml_entities_are_not_resolved(tmp_path):
    secret = _write(tmp_path, "secret.txt", "42")
    path = _write(tmp_path, "s.xml", f"""<?xml version="1.0"?>
<!DOCTYPE Scenario [<!ENTITY leak SYSTEM "file://{secret}">]>
<Scenario><action t="1"><variable id="m::v"><real value="&leak;"/></variable></action>
</Scenario>""")
    try:
        scenario = read_scenario(path)
    except InputError as error:  # refused outright is as safe
        assert all("42" not in problem for problem in error.problems)
    else:
        assert scenario.events[0].value != "42"


def test_other_suffixes_and_shapes_are_refused(tmp_path):
    assert "a scenario file is .json, .yml or .yaml" in _problems(
        _write(tmp_path, "s.txt", "{}"))[0]
    assert "'events' is missing or not a list" in _problems(
        _write(tmp_path, "s.json", '{"defaults": {}}'))[0]
    assert "not an ECOS <Scenario>" in _problems(_write(tmp_path, "s.xml", "<Other/>"))[0]
    assert "give MODEL::VARIABLE" in _problems(_write(
        tmp_path, "t.xml", '<Scenario><action t="1"><variable id="v"><real value="1"/>'
        "</variable></action></Scenario>"))[0]
