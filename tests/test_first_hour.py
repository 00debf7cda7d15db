"""The first hour with dsim (issue 32): what a new user meets first, each checked on the
real scenes of build/: ``--version``, a subcommand's own usage, studies that check
their columns before they run, honest sensitivity tables, a step that does not fit
the span, ``dsim info``'s summary and array sizes, and the Python API's results."""
from __future__ import annotations

import csv
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.planning.parameters import JOINT_COEFFICIENTS
from dsim.master.sweeps import sensitivity
from dsim.master.sweeps.design import Design, parse_vary
from dsim.master.sweeps.table import Point, count_states, state
from dsim.master.tools.cli import main

ROOT = Path(__file__).resolve().parent.parent


def _one_error(capsys) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in lines[0], lines
    return lines[0]


# --- 1. version and usage ----------------------------------------------------------------
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
    root = Path(__file__).resolve().parent.parent
    text = tomllib.loads((root / "pyproject.toml").read_text())["project"]["description"]
    for said in ("FMI 1.0, 2.0 and 3.0", "co-simulation and Model Exchange", "SSP"):
        assert said in text, text


def test_a_subcommands_wrong_option_prints_that_subcommands_usage(built):
    done = subprocess.run([sys.executable, "-m", "dsim", "run",
                           str(built["ssp"] / "spring_mass_linear.ssp"), "--stpo", "1"],
                          cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.startswith("usage: dsim run ") and "--output-interval" in done.stderr
    assert "dsim run: error: unrecognized arguments: --stpo 1" in done.stderr


# --- 2. studies check before they run ----------------------------------------------------
def test_a_misspelled_kpi_is_refused_before_the_first_point(built, tmp_path, capsys):
    """Regression: --kpi 'max(right.y[2])' ran every point, printed nan and exited 0."""
    out = tmp_path / "sweep"
    assert main(["sweep", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "0.1",
                 "--step", "0.01,0.02", "--kpi", "max(right.y[2])", "--out", str(out)]) == 2
    line = _one_error(capsys)
    assert "no recorded column matches 'right.y[2]'" in line and "closest: right.x[2]" in line
    assert not out.exists()  # nothing ran, nothing written
    assert main(["sweep", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "0.1",
                 "--step", "0.01,0.02", "--kpi", "final(right.x*)", "--out", str(out)]) == 2
    assert "final needs one column; 'right.x*' matches 2" in _one_error(capsys)
    # the columns checked are those a run writes: outputs, joint forces, as chosen
    from dsim.master.sweeps.sweep import recorded_columns

    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    every = recorded_columns(dsim.prepare(scene))
    with open(dsim.simulate(scene, stop=0.02, out=tmp_path / "r.csv",
                            handle_signals=False).files["csv"]) as file:
        assert every == file.readline().strip().split(",")
    assert "j1.f_x" in every
    assert recorded_columns(dsim.prepare(scene, outputs=["right.x*"])) == [
        "time", "right.x[1]", "right.x[2]"]


def test_a_misspelled_vary_name_is_refused_with_the_closest(built, tmp_path, capsys):
    scene = str(built["ssp"] / "spring_mass_nonlinear.ssp")
    out = tmp_path / "sweep"
    assert main(["sweep", scene, "--vary", "stepp=0.01,0.02", "--out", str(out)]) == 2
    assert "'stepp' is not a setting (closest: step" in _one_error(capsys)
    assert main(["sweep", scene, "--vary", "right.m[3]=5,6", "--out", str(out)]) == 2
    assert "m[3] would have no effect" in _one_error(capsys)
    assert main(["sweep", scene, "--vary", "j1.k3=5,6", "--out", str(out)]) == 2
    assert "it has: k0, k1, c0, c1; closest: k1" in _one_error(capsys)
    assert not out.exists()


# --- 3. honest statistics ----------------------------------------------------------------
def test_src_intervals_are_the_least_squares_ones():
    """One factor: the SRC is Pearson's r and its interval the slope's standard error
    of scipy's linregress on the standardized data, times Student's t."""
    from scipy import stats

    rng = np.random.default_rng(4)
    x = rng.uniform(size=(20, 1))
    y = 2 * x[:, 0] + rng.normal(scale=0.5, size=20)
    coefficients, halves, r2 = sensitivity.src_with_intervals(x, y)
    fit = stats.linregress((x[:, 0] - x.mean()) / x.std(), (y - y.mean()) / y.std())
    assert coefficients[0] == pytest.approx(fit.slope, rel=1e-12)
    assert halves[0] == pytest.approx(fit.stderr * stats.t.ppf(0.975, 18), rel=1e-9)
    assert r2 == pytest.approx(fit.rvalue ** 2, rel=1e-12)


def test_correlated_factors_are_said_and_src_squared_is_no_variance_share():
    """Two factors correlated at r = 0.8 in the sample: the table says so and does not
    call SRC^2 a variance share; a third factor with no effect is marked ~0."""
    rng = np.random.default_rng(1)
    a = rng.uniform(size=40)
    b = 0.8 * a + 0.6 * rng.uniform(size=40)
    c = rng.uniform(size=40)
    configurations = [{"p.a": float(u), "p.b": float(v), "p.c": float(w)}
                      for u, v, w in zip(a, b, c)]
    design = Design([parse_vary("p.a=0:1", True), parse_vary("p.b=0:1.4", True),
                     parse_vary("p.c=0:1", True)], "lhs", 40, 0)
    y = a + b + 0.01 * rng.normal(size=40)
    indices = sensitivity.analyse(design, configurations, {"k": y})
    r = np.corrcoef(a, b)[0, 1]
    assert r > sensitivity.CORRELATED
    caution = sensitivity.cautions(indices, "k")
    assert len(caution) == 1 and f"r = {r:.3f}" in caution[0]
    srcs = {i.factor: i for i in indices if i.measure == "SRC"}
    assert f"add up to {sum(i.value ** 2 for i in srcs.values()):.2f}" in caution[0]
    text = sensitivity.markdown(indices)
    assert "variance share where" not in text and "not a variance share here" in text
    assert srcs["p.c"].spans_zero and not srcs["p.a"].spans_zero
    assert re.search(r"\| p\.c \| -?0\.\d{3} ± 0\.\d{3} ~0 \|", text), text
    assert "~0: its 95 % confidence interval spans zero" in text
    # uncorrelated factors keep the reading of SRC^2 as a share
    plain = sensitivity.analyse(design, [{**p, "p.b": float(v)} for p, v in
                                         zip(configurations, rng.uniform(size=40))],
                                {"k": a + 0.01 * rng.normal(size=40)})
    assert not sensitivity.cautions(plain, "k")
    assert "variance share where R^2 is close to 1" in sensitivity.markdown(plain)


# --- 4. a step that does not fit the span ------------------------------------------------
@pytest.mark.parametrize("step, said", [
    ("20", "step 20 s is longer than the span 0 .. 10 s: the run takes one step of 10 s"),
    ("3", "step 3 s does not divide the span 0 .. 10 s: the run takes 3 steps of 3 s and "
          "a last one of 1 s")])
def test_a_step_that_does_not_fit_the_span_is_said_and_refused_when_strict(
        built, tmp_path, capsys, step, said):
    scene = str(built["ssp"] / "spring_mass_linear.ssp")
    assert main(["validate", scene, "--stop", "10", "--step", step]) == 0
    assert said in capsys.readouterr().err
    assert main(["validate", scene, "--stop", "10", "--step", step, "--strict"]) == 2
    assert said in _one_error(capsys)
    assert main(["run", scene, "--stop", "10", "--step", step, "--out",
                 str(tmp_path / "r.csv")]) == 0
    shown = capsys.readouterr()
    assert said in shown.err and f"({said.split(': ', 1)[1]})" in shown.out
    result = dsim.simulate(scene, stop=10.0, step=float(step), handle_signals=False)
    assert result.ok and any(said in w for w in result.warnings)
    assert result.steps == (1 if step == "20" else 4)
    assert dsim.simulate(scene, stop=10.0, step=2.5, handle_signals=False).warnings == []


# --- 5. dsim info ------------------------------------------------------------------------
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


def test_an_array_entry_past_the_scenes_size_is_refused(built, capsys, tmp_path):
    scene = str(built["ssp"] / "spring_mass_nonlinear.ssp")
    assert main(["run", scene, "--set", "right.m[3]=500", "--out", str(tmp_path / "r.csv")]) == 2
    line = _one_error(capsys)
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


# --- 7. the Python API -------------------------------------------------------------------
def test_a_missing_column_names_the_closest(built):
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.05,
                           handle_signals=False)
    with pytest.raises(KeyError) as missing:
        result["right.y[2]"]
    assert "no column 'right.y[2]' in the results (closest: right.x[2]" in str(missing.value)
    assert missing.value.closest[0] == "right.x[2]"
    assert np.array_equal(result["right.x[2]"], result.signals["right.x[2]"])


def test_to_pandas_is_the_signals_indexed_by_time(built, tmp_path, monkeypatch):
    pandas = pytest.importorskip("pandas")
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.05,
                           out=tmp_path / "r.csv", handle_signals=False)
    frame = result.to_pandas()
    assert frame.index.name == "time" and list(frame.columns) == [
        n for n in result.signals if n != "time"]
    assert np.array_equal(frame["right.x[2]"].to_numpy(), result["right.x[2]"])
    assert np.array_equal(frame.index.to_numpy(), result["time"])
    read = pandas.read_csv(tmp_path / "r.csv", index_col="time")
    assert np.allclose(read.to_numpy(), frame.to_numpy(), rtol=1e-15, atol=0)
    monkeypatch.setitem(sys.modules, "pandas", None)  # as if it were not installed
    with pytest.raises(ImportError, match="pip install pandas"):
        result.to_pandas()


def test_each_point_has_one_state_word():
    points = [Point({}, "completed", True), Point({}, "completed", False),
              Point({}, "failed"), Point({}, "bad input"), Point({}, "interrupted")]
    assert [state(p) for p in points] == ["completed", "unstable", "failed", "refused",
                                          "interrupted"]
    assert count_states(points) == ("1 completed, 1 unstable, 1 failed, 1 refused, "
                                    "1 interrupted")
    assert [p.finished for p in points] == [True, True, True, True, False]


def test_the_sweep_summary_says_each_points_state(built, tmp_path, capsys):
    out = tmp_path / "sweep"
    assert main(["sweep", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "2",
                 "--step", "0.02", "--predictor", "quadratic", "--vary",
                 "coupling=explicit,iterative", "--out", str(out)]) == 0
    shown = capsys.readouterr().out
    assert "sweep       2 points (1 completed, 1 failed)" in shown
    with open(out / "sweep.csv", newline="") as file:
        failed = [r["point"] for r in csv.DictReader(file) if r["status"] == "failed"]
    assert f"failed      point {failed[0]}: the run failed" in shown
    table = (out / "sweep.md").read_text()
    assert "(unstable)" not in table and "| failed |" in table
