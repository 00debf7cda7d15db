"""The scenes and scenario files the scenario tests share: the offset FMU
(tests/support/third_party/offset.c: output = input + constant, as libcosim's test
slave) alone as libcosim's test runs it, and two of them connected."""
from __future__ import annotations

from pathlib import Path

from tests.support.scene_files import component, scene_folder, ssd
from tests.support.third_party.build import OFFSET_VARIABLES, c_fmu

#: the events of libcosim's scenario1 test, on a component named as libcosim's test
#: names its slave; written by us, in libcosim's format (JSON, then the same as YAML)
SCENARIO1_JSON = """{
  "defaults": {"model": "slave uno", "variable": "realOut", "action": "override"},
  "events": [
    {"time": 0.5, "variable": "realIn", "action": "bias", "value": 1.001},
    {"time": 0.2, "value": -1.0},
    {"time": 0.3, "action": "reset"},
    {"time": 0.65, "variable": "intIn", "value": 2},
    {"time": 0.8, "variable": "intOut", "value": 5}
  ],
  "end": 1.0
}
"""
SCENARIO1_YAML = """# the events of SCENARIO1_JSON, in YAML with the informative keys
defaults:
  model: slave uno
  variable: realOut
  causality: output
  type: real
  action: override
events:
  - time: 0.5
    variable: realIn
    causality: input
    action: bias
    value: 1.001
  - time: 0.2
    value: -1
  - time: 0.3
    action: reset
  - time: 0.65
    variable: intIn
    causality: input
    type: integer
    value: 2
  - time: 0.8
    variable: intOut
    type: integer
    value: 5
end: 1
"""


def offset_scenes(folder: Path) -> dict:
    """Build the offset FMU (consistent starts, and libcosim's mock's variant) and the
    scenes of the tests: ``single`` and ``mock`` (one component "slave uno", 0 .. 1.1 s
    in steps of 0.1 s), ``chain`` (a.realOut -> b.realIn, a.intOut -> b.intIn, 0 .. 1 s
    in steps of 0.1 s); the paths by name, with the FMUs."""
    folder = Path(folder)
    fmu = c_fmu(folder / "fmus", "offset", "offset.c", OFFSET_VARIABLES)
    mock = c_fmu(folder / "fmus", "offset_mock", "offset.c", OFFSET_VARIABLES,
                 defines=("MOCK_INPUTS_ZERO",))
    one = [component("slave uno", "resources/offset.fmu")]
    scenes = {"fmu": fmu, "mock_fmu": mock}
    for name, source in (("single", fmu), ("mock", mock)):
        scenes[name] = scene_folder(folder / name, ssd("scenario1", one, stop=1.1,
                                                       master='step="0.1"'),
                                    {"offset.fmu": source})
    chain = ssd("chain", [component("a", "resources/offset.fmu"),
                          component("b", "resources/offset.fmu")],
                [("a", "realOut", "b", "realIn"), ("a", "intOut", "b", "intIn")],
                stop=1.0, master='step="0.1"')
    scenes["chain"] = scene_folder(folder / "chain", chain, {"offset.fmu": fmu})
    return scenes
