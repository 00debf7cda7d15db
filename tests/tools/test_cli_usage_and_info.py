"""What a new user of the command line meets first, on the real scenes of build/:
``--version``, a subcommand's own usage on a wrong option, and ``dsim info``: a summary
that fits a screen, one line per FMU file in a large scene, arrays to the scene's size
with a unit column under ``--all``."""
from __future__ import annotations

import re
import subprocess
import sys

import pytest

import dsim
from dsim.master.planning.parameters import JOINT_COEFFICIENTS
from dsim.master.tools.cli import main
from tests.support.paths import ROOT


def test_version_comes_from_the_package_metadata(capsys):
    from importlib.metadata import version

    assert dsim.__version__ == version("dsim")
    with pytest.raises(SystemExit) as ended:
        main(["--version"])
    assert ended.value.code == 0 and capsys.readouterr().out.strip() == f"dsim {version('dsim')}"


def test_the_package_description_says_what_dsim_runs():
    """pyproject's description named FMI 2.0 only; dsim runs FMI 1.0, 2.0 and 3.0 FMUs,
    both interfaces, from SSP files."""
    tomllib = pytest.importorskip("tomllib")
    text = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["description"]
    for said in ("FMI 1.0, 2.0 and 3.0", "co-simulation and Model Exchange", "SSP"):
        assert said in text, text


def test_a_subcommands_wrong_option_prints_that_subcommands_usage(built):
    done = subprocess.run([sys.executable, "-m", "dsim", "run",
                           str(built["ssp"] / "spring_mass_linear.ssp"), "--stpo", "1"],
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.startswith("usage: dsim run ") and "--output-interval" in done.stderr
    assert "dsim run: error: unrecognized arguments: --stpo 1" in done.stderr


def test_info_is_a_summary_that_fits_a_screen(built, capsys):
    assert main(["info", str(built["ssp"] / "spring_mass_nonlinear.ssp")]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert len(lines) <= 24, out  # was 169
    assert "FMUs (1 file for 2 components):" in out
    assert "  SpringMass.fmu: SpringMass, FMI 2.0 co-simulation; state yes" in out
    assert "components (2; 2 glued, 0 free):" in out
    # the joint's law as numbers, never Python tuples, and only its own coefficients
    assert "j1: left.P -> right.Q dofs x, flexible, displacement k0=100 k1=1000 c0=14.14 " \
           "c1=14140" in out
    assert "(14." not in out and " xi" not in out and "omega" not in out
    count = re.search(r"can be set: (\d+) variables of 2 components", out)
    plan = dsim.prepare(built["ssp"] / "spring_mass_nonlinear.ssp")
    assert int(count.group(1)) == sum(len(dsim.free_settable(plan, i)) for i in range(2))
    assert "right: arrays m, k_ground, k1_ground, c_ground, ... used to [2] of [4] (n = 2" in out


def test_a_large_scene_prints_one_line_per_fmu_file(built, capsys):
    assert main(["info", str(built["ssp"] / "chain_1000.ssp")]) == 0
    out = capsys.readouterr().out
    assert len(out.splitlines()) < 45, out
    assert "FMUs (1 file for 1000 components):" in out
    assert "... 988 more components (dsim info --all lists every one)" in out
    assert "... 987 more joints" in out


def test_info_all_shows_arrays_to_the_scenes_size_with_a_unit_column(built, capsys):
    assert main(["info", "--all", str(built["ssp"] / "spring_mass_nonlinear.ssp")]) == 0
    out = capsys.readouterr().out
    right = out[out.index("  right:"):out.index("joints (1):")]
    table = [line.split() for line in right.splitlines() if line.startswith("        ")]
    assert table[0][:4] == ["name", "type", "unit", "causality/variability"]
    names = [row[0] for row in table[1:]]
    assert "m[1]" in names and "m[2]" in names and "m[3]" not in names and "m[4]" not in names
    left = out[out.index("  left:"):out.index("  right:")]
    assert " m[1] " in left and " m[2] " not in left  # left has n = 1
    assert "      k0: " + JOINT_COEFFICIENTS["k0"][1] in out
