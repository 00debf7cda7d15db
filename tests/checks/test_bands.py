"""Regression bands with a floor that round-off cannot cross (docs/ci.md, "How the
bands are set"): the band arithmetic, and the kernel study that measures the floor
with real runs under forced OpenBLAS kernels."""
import json
import shutil

import numpy as np
import pytest

from dsim.master.tools.cli import main
from dsim.master.checks.compare import EPS, NOISE_FACTOR, ULPS, band, compare_files
from dsim.master.checks.kernel_study import openblas_cores, supported_kernels
from dsim.master.checks.regress import find_cases
from tests.support.results import write_csv as write

TIMES = np.linspace(0.0, 1.0, 11)
#: a parallelogram-like pair: crank.theta is physics, coupler.theta zero in exact
#: arithmetic (its values are round-off), omega the same
COLUMNS = {"crank.theta": 3.0 * TIMES, "coupler.theta": 1e-16 * np.sin(7 * TIMES),
           "crank.omega": np.full(11, 3.0), "coupler.omega": 8e-13 * np.cos(5 * TIMES)}


def nudged(column, by, at=6):
    columns = {name: values.copy() for name, values in COLUMNS.items()}
    columns[column][at] += by
    return columns


def test_band_arithmetic():
    # rtol decides for a column of its own size
    assert band(2.0, 1e-6, 0.0) == (2e-6, "rtol")
    assert band(2.0, 1e-6, 1e-3) == (pytest.approx(1e-3 + 2e-6), "rtol")
    # a column that is pure round-off: its own peak is no scale, its quantity's is
    assert band(1e-16, 1e-6, 0.0, scale=3.0) == (ULPS * EPS * 3.0, "ulps")
    assert ULPS * EPS * 3.0 == pytest.approx(1.0658e-14, rel=1e-4)
    # measured noise between kernels: ten times it
    assert band(8e-13, 1e-6, 0.0, scale=3.0, noise=1.3e-12) == (NOISE_FACTOR * 1.3e-12, "noise")
    # a floor never tightens a band rtol sets
    assert band(3.0, 1e-6, 0.0, scale=3.0, noise=1e-12) == (3e-6, "rtol")


def test_a_pure_round_off_column_gets_the_ulps_floor_of_its_quantity(tmp_path):
    write(tmp_path / "ref.csv", TIMES, COLUMNS)
    floor = ULPS * EPS * 3.0  # the largest theta column's peak
    write(tmp_path / "inside.csv", TIMES, nudged("coupler.theta", 0.9 * floor))
    write(tmp_path / "outside.csv", TIMES, nudged("coupler.theta", 1.5 * floor))
    inside = compare_files(tmp_path / "inside.csv", tmp_path / "ref.csv")
    theta = inside.differences[1]
    assert inside.passed and theta.source == "ulps" and theta.allowed == floor
    outside = compare_files(tmp_path / "outside.csv", tmp_path / "ref.csv")
    assert [d.column for d in outside.failed] == ["coupler.theta"]
    assert outside.failed[0].first[0] == pytest.approx(0.6)


def test_recorded_noise_sets_the_floor_and_a_json_without_noise_still_works(tmp_path, capsys):
    write(tmp_path / "ref.csv", TIMES, COLUMNS)
    write(tmp_path / "run.csv", TIMES, nudged("coupler.omega", 5e-12))
    # without noise (a baseline JSON of before the kernel study): the ulps floor only,
    # 16 eps * 3 = 1.07e-14 < 5e-12: it differs
    (tmp_path / "old.json").write_text(json.dumps({"settings": {}, "rtol": 1e-6}))
    assert main(["compare", str(tmp_path / "run.csv"), str(tmp_path / "ref.csv"),
                 "--noise", str(tmp_path / "old.json")]) == 1
    out = capsys.readouterr().out
    assert "coupler.omega" in out and "ulps" in out and "DIFFERS from t = 0.6 s" in out
    # measured 1e-12 between kernels: the band is 1e-11 and 5e-12 is inside it
    (tmp_path / "new.json").write_text(json.dumps(
        {"settings": {}, "rtol": 1e-6, "noise": {"coupler.omega": 1e-12}}))
    assert main(["compare", str(tmp_path / "run.csv"), str(tmp_path / "ref.csv"),
                 "--noise", str(tmp_path / "new.json")]) == 0
    out = capsys.readouterr().out
    assert "coupler.omega: floor: 10 x 1e-12 measured between BLAS kernels" in out
    # bad noise is bad input: one line, exit 2
    (tmp_path / "bad.json").write_text(json.dumps({"noise": {"coupler.omega": -1}}))
    assert main(["compare", str(tmp_path / "run.csv"), str(tmp_path / "ref.csv"),
                 "--noise", str(tmp_path / "bad.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "noise must map column names to non-negative numbers" in err[0]


def test_a_baseline_json_without_noise_reads_as_none_measured(tmp_path):
    (tmp_path / "s.ssp").write_bytes(b"")
    (tmp_path / "baselines").mkdir()
    (tmp_path / "baselines" / "s.json").write_text(json.dumps({"settings": {"stop": 1.0}}))
    (tmp_path / "baselines" / "s.csv").write_text("time\n0.0\n")
    (case,), _ = find_cases(tmp_path)
    assert case.noise == {} and case.rtol == 1e-6 and case.settings == {"stop": 1.0}


STUDY_KERNELS = [k for k in ("Prescott", "Sandybridge") if k in supported_kernels()]


@pytest.mark.skipif(not openblas_cores() or len(STUDY_KERNELS) < 2,
                    reason="needs numpy on OpenBLAS and a CPU with SSE3 and AVX")
def test_kernel_study_measures_noise_and_a_result_beyond_it_regresses(built, tmp_path,
                                                                     capsys):
    """The singular four bar under two forced kernels: coupler.omega is zero in exact
    arithmetic and the kernels' round-off differs, so the study records a nonzero
    noise for it; a baseline moved by more than the band it sets regresses."""
    scenes = tmp_path / "scenes"
    (scenes / "baselines").mkdir(parents=True)
    shutil.copy(built["ssp"] / "four_bar_singular_penalized.ssp", scenes)
    spec = scenes / "baselines" / "four_bar_singular_penalized.json"
    spec.write_text(json.dumps({"settings": {"stop": 0.1}, "rtol": 1e-6}))
    assert main(["regress", str(scenes), "--update", "--kernels",
                 ",".join(STUDY_KERNELS)]) == 0
    said = capsys.readouterr().err
    assert "kernel study: " in said and "besides the default" in said
    record = json.loads(spec.read_text())
    assert record["settings"] == {"stop": 0.1} and record["rtol"] == 1e-6  # kept
    # the kernels asked for ran, unless one is the code this process runs already (the
    # suite itself may run under OPENBLAS_CORETYPE=Prescott): then it is the default
    ran = set(record["study"]["kernels"]) | set(record["study"].get("same code as", {}))
    assert set(STUDY_KERNELS) <= ran, record["study"]
    assert record["study"]["numpy"] == np.__version__
    noise = record["noise"]["coupler.omega"]
    assert 1e-16 < noise < 1e-9  # round-off of a zero, not a change of the dynamics
    assert record["noise"].get("crank.theta", 0.0) == 0.0  # driven: the same everywhere
    assert main(["regress", str(scenes)]) == 0
    capsys.readouterr()
    # the baseline's coupler.omega moved by 3 bands at t = 0.05 s: a regression
    baseline = scenes / "baselines" / "four_bar_singular_penalized.csv"
    header, *rows = baseline.read_text().splitlines()
    column = header.split(",").index("coupler.omega")
    values = rows[5].split(",")
    values[column] = repr(float(values[column]) + 3 * NOISE_FACTOR * noise)
    rows[5] = ",".join(values)
    baseline.write_text("\n".join([header] + rows) + "\n")
    assert main(["regress", str(scenes)]) == 1
    err = capsys.readouterr().err
    assert "coupler.omega: outside the band from t = 0.05 s" in err
    assert f"{NOISE_FACTOR:g} x {noise:.3g} measured between BLAS kernels" in err


def test_kernel_options_are_checked_before_anything_runs(built, tmp_path, capsys):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    assert main(["regress", str(scenes), "--kernels", "Prescott"]) == 2
    assert main(["regress", str(scenes), "--update", "--kernels", "Pentium4"]) == 2
    lacking = [k for k in ("SkylakeX", "Haswell") if k not in supported_kernels()]
    if lacking:
        assert main(["regress", str(scenes), "--update", "--kernels", lacking[0]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "give --update too" in err[0]
    assert "Pentium4: not OpenBLAS kernels dsim can force" in err[1]
    assert len(err) == 2 + bool(lacking) and all(e.startswith("dsim: error: ") for e in err)
    if lacking:
        assert f"{lacking[0]} needs" in err[2]
