"""A table's inputs within a step (docs/inputs.md, running/fmi/table_inputs.py): a Model
Exchange FMU integrated by dsim follows the table's line over the step, a co-simulation
FMU that can interpolate inputs gets its slope; any other holds the step's start value."""
import shutil

import numpy as np
import pytest

import dsim
from tests.support.scenes import archive_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")

#: a ramp of 10 per s from 0 to 1 s, a row at 0.55 s inside a step, then held
TABLE = "time,{c}.{v}\n0,0\n0.55,5.5\n1,10\n"


def test_model_exchange_follows_the_table_to_the_step_end(tmp_path):
    from tests.support.third_party.kinds.build import build_fmu

    fmu = build_fmu(tmp_path, "feedthrough", "2.0", ("ModelExchange",), name="feedthrough")
    scene = archive_scene(tmp_path / "me.ssp", {"f": (fmu, "ModelExchange", "")}, stop=1.2,
                          step=0.1)
    path = tmp_path / "u.csv"
    path.write_text(TABLE.format(c="f", v="u"))
    result = dsim.simulate(scene, inputs=path)
    assert result.status == "completed", result.message
    # y = 0.5 u + 1 at each step's end, where the line along the table is the table's
    # own value at that time (10 t up to 1 s, held after): not the step's start value
    times = result["time"]
    expected = 0.5 * np.minimum(10 * times, 10.0) + 1.0
    assert np.allclose(result["f.y"], expected, rtol=0, atol=1e-12)


def test_co_simulation_that_interpolates_gets_the_slope(tmp_path):
    from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu

    fmus = {"plain": c_fmu(tmp_path, "osc", "oscillator.c", OSCILLATOR_VARIABLES),
            "slope": c_fmu(tmp_path, "osc_i", "oscillator.c", OSCILLATOR_VARIABLES,
                           defines=("INTERPOLATE",), interpolate_inputs=True)}
    path = tmp_path / "f.csv"
    path.write_text(TABLE.format(c="o", v="F_in"))
    force = {}
    for kind, fmu in fmus.items():
        scene = archive_scene(tmp_path / f"{kind}.ssp", {"o": (fmu, "", "")}, stop=1.2,
                              step=0.1)
        result = dsim.simulate(scene, inputs=path)
        assert result.status == "completed", result.message
        # m = k = 1: the force the FMU took at each step's end is a + s
        force[kind] = result["o.a"] + result["o.s"]
        functions = result.statistics["components"]["o"]["functions"]
        slopes = functions.get("fmi2SetRealInputDerivatives", {}).get("calls", 0)
        assert slopes == (12 if kind == "slope" else 0)  # one per step
    times = result["time"]
    ramp = np.minimum(10 * times, 10.0)
    # held: the value at the step's start; with the slope: the table's at its end
    assert np.allclose(force["plain"][1:], ramp[:-1], rtol=0, atol=1e-9)
    assert np.allclose(force["slope"], ramp, rtol=0, atol=1e-9)
