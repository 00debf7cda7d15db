"""Start forces: a flexible joint that starts stretched is preloaded by default
(start="auto"), as it is in one model; start="rest" stays available and says
what it costs."""
import zipfile

import numpy as np
import pytest

import dsim
from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain

STRETCH = 0.05  # m: m1 starts this far from m2, the joint spring between them stretched


def stretched_scene(built, tmp_path, nonlinear: bool):
    """spring_mass_<linear|nonlinear> with m1 starting STRETCH to the right."""
    name = "spring_mass_nonlinear" if nonlinear else "spring_mass_linear"
    target = tmp_path / f"{name}_stretched.ssp"
    with zipfile.ZipFile(built["ssp"] / f"{name}.ssp") as old, \
            zipfile.ZipFile(target, "w") as new:
        for item in old.namelist():
            data = old.read(item)
            if item == "resources/left.ssv":
                data = data.replace(b"  </ssv:Parameters>",
                                    b'    <ssv:Parameter name="x0[1]"><ssv:Real value="'
                                    + repr(STRETCH).encode() + b'"/></ssv:Parameter>\n'
                                    b"  </ssv:Parameters>")
            new.writestr(item, data)
    return target


def monolithic(nonlinear: bool, steps: int, step: float = 0.01) -> np.ndarray:
    """m3's position in the one-model chain of eq. 5.37 with m1 starting stretched."""
    params = ChainParameters(n=3)
    params.m[:3] = 10.0
    params.k_ground[0] = 100.0
    params.k[:2] = (100.0, 100.0)
    params.c[0] = 2 * 0.707 * 10
    if nonlinear:
        params.k1[0], params.c1[0] = 1000.0, 2 * 0.707 * 1e4
    params.F0[2] = 10.0
    params.x0[0] = STRETCH
    return SpringMassChain(params).history(steps, step)[:, 2]


@pytest.mark.parametrize("nonlinear", [False, True], ids=["linear", "nonlinear"])
def test_a_stretched_flexible_joint_starts_preloaded_by_default(built, tmp_path, nonlinear):
    scene = stretched_scene(built, tmp_path, nonlinear)
    reference = monolithic(nonlinear, 300)
    peak = np.max(np.abs(reference))
    auto = dsim.simulate(scene, stop=3.0)
    rest = dsim.simulate(scene, stop=3.0, start="rest")
    auto_error = np.max(np.abs(auto["right.x[2]"] - reference)) / peak
    rest_error = np.max(np.abs(rest["right.x[2]"] - reference)) / peak
    # the law's force at the start stretch, on port b (right.Q) pulling towards m1
    k0 = 100.0 + (1000.0 * STRETCH if nonlinear else 0.0)
    assert auto["j1.f_x"][0] == pytest.approx(k0 * STRETCH, rel=1e-12)
    assert auto.warnings == [] and auto_error < 1e-8   # measured 1.1e-11 / 6.5e-10
    # rest: 6.5e-4 / 3.3e-4 of the peak, the start's missing force carried along
    assert rest["j1.f_x"][0] == 0.0 and rest_error > 1e3 * auto_error
    assert len(rest.warnings) == 1
    assert rest.warnings[0].startswith("start='rest': joint 'j1' (j1.f_x): extension -0.05, ")
    assert "starts with zero force: the start is inconsistent" in rest.warnings[0]


def test_the_rest_warning_reaches_the_command_line(built, tmp_path, capsys):
    from dsim.master.tools.cli import main

    scene = stretched_scene(built, tmp_path, False)
    assert main(["run", str(scene), "--start", "rest", "--stop", "0.1", "--quiet",
                 "--out", str(tmp_path / "run.csv")]) == 0
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dsim: warning: start='rest': joint 'j1'")


def test_a_start_at_rest_in_equilibrium_needs_no_warning(built):
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.1, start="rest")
    assert result.ok and result.warnings == []
