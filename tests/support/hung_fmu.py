"""The C oscillator built with -DHANG_TIME: it never returns from the step that reaches
t = 0.0505 s (step 51 of 1 ms).  A module's fixture, imported where it is used."""
import shutil

import pytest

from tests.support.scene_files import component, scene_folder, ssd
from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu

#: steps that converge before the hang (t = 0.001 .. 0.050 s), rows with the start's
CONVERGED = 50
ROWS = CONVERGED + 1


@pytest.fixture(scope="module")
def hung_scene(tmp_path_factory):
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    folder = tmp_path_factory.mktemp("hung")
    fmu = c_fmu(folder / "c", "oscillator", "oscillator.c", OSCILLATOR_VARIABLES,
                defines=("HANG_TIME=0.0505",))
    text = ssd("hung", [component("osc", "resources/oscillator.fmu",
                                  {"m": 1.0, "k": 100.0, "s0": 0.01}, outputs=["s"])],
               stop=10.0, master='step="0.001"')
    return scene_folder(folder / "scene", text, {"oscillator.fmu": fmu})
