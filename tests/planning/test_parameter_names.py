"""What a parameter name may name: an array entry within the scene's size (raised in
the same run, it is one), and a joint's own coefficients, from one list that dsim info,
the errors and docs/parameters.md share (master/planning/parameters.py)."""
import pytest

import dsim
from dsim.master.planning.parameters import JOINT_COEFFICIENTS
from dsim.master.tools.cli import main
from tests.support.paths import ROOT
from tests.support.runs import one_error


def test_an_array_entry_past_the_scenes_size_is_refused(built, capsys, tmp_path):
    scene = str(built["ssp"] / "spring_mass_nonlinear.ssp")
    assert main(["run", scene, "--set", "right.m[3]=500", "--out", str(tmp_path / "r.csv")]) == 2
    line = one_error(capsys)
    assert "parameter 'right.m[3]'" in line and "(n = 2)" in line and "right.n" in line
    assert not (tmp_path / "r.csv").exists()
    # with the size raised in the same run it is a mass of the chain, and moves it
    plan = dsim.prepare(scene, parameters={"right.n": 3, "right.m[3]": 500})
    assert plan.scene.component("right").parameters["m[3]"] == ("Real", 500.0)


def test_one_list_of_joint_coefficients_for_info_errors_and_docs(built, capsys):
    docs = (ROOT / "docs" / "parameters.md").read_text()
    for key, (kind, meaning) in JOINT_COEFFICIENTS.items():
        assert f"| `{key}` | {kind} | {meaning} |" in docs, key
    with pytest.raises(dsim.InputError) as refused:
        dsim.prepare(built["ssp"] / "spring_mass_nonlinear.ssp", parameters={"j1.k3": 1})
    assert refused.value.problems == ["parameter 'j1.k3': joint 'j1' has no coefficient 'k3' "
                                      "(it has: k0, k1, c0, c1; closest: k1)"]
