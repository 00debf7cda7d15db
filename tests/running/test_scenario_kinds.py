"""A scenario's input events on every FMU kind dsim runs (docs/scenarios.md): FMI 1.0
and 3.0 co-simulation, FMI 2.0 and 3.0 Model Exchange (integrated by dsim) and FMI 2.0
co-simulation, on the C feedthrough block y = g u + c (g = 0.5, c = 1) of
tests/support/third_party/kinds, its input u fed by no connection."""
import json
import shutil

import pytest

import dsim
from tests.support.scenes import archive_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")


@pytest.mark.parametrize("version, interface", [
    ("1.0", "CoSimulation"), ("2.0", "CoSimulation"), ("2.0", "ModelExchange"),
    ("3.0", "CoSimulation"), ("3.0", "ModelExchange")])
def test_an_input_event_acts_on_the_step_that_starts_at_its_point(tmp_path, version,
                                                                  interface):
    from tests.support.third_party.kinds.build import build_fmu

    fmu = build_fmu(tmp_path, "feedthrough", version, (interface,), name="feedthrough")
    scene = archive_scene(tmp_path / "scene.ssp", {"f": (fmu, interface, "")}, stop=1.0,
                          step=0.1)
    scenario = tmp_path / "s.json"
    scenario.write_text(json.dumps({"defaults": {"model": "f", "variable": "u"}, "events": [
        {"time": 0.5, "action": "override", "value": 4.0},
        {"time": 0.7, "action": "bias", "value": 1.0}]}))
    result = dsim.simulate(scene, scenario=scenario)
    # u = 0 (its start) until the step from 0.5 (y = 1), then 4 (y = 3); from the step
    # from 0.7 the start 0 plus the bias 1 (y = 1.5): each shows in the row after its point
    assert result["f.y"].tolist() == [1.0] * 6 + [3.0] * 2 + [1.5] * 3
    assert [(a["action"], a["old"], a["new"]) for a in
            result.statistics["scenario"]["applied"]] == [("override", 0.0, 4.0),
                                                           ("bias", 4.0, 1.0)]
