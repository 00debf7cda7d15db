"""A sweep of a scene with no monolithic twin measures its points against dsim's own
reference run (the strong coupling, an error-controlled step at a tenth of the
tolerance), not against its tightest point, which may be a causal run far off; where
that run cannot be made, against the tightest point, and it says which.

The two-mass oscillator split in two C FMUs (tests/support/third_party/kinds), whose
closed form is the truth the errors are checked against."""
from __future__ import annotations

import csv
import shutil

import numpy as np
import pytest

from dsim.master.recording.results import read_columns
from dsim.master.tools.cli import main
from tests.support.closed_forms import LINKS, exact_x1
from tests.support.scenes import archive_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")

PEAK = 0.1  # the closed form's max |x1| over the run (m): x1(0)


@pytest.fixture(scope="module")
def masses(tmp_path_factory):
    from tests.support.third_party.kinds.build import build_fmu, mass_fmus

    folder = tmp_path_factory.mktemp("masses")
    return mass_fmus(folder, interfaces=("CoSimulation",)) | {
        "fixed": build_fmu(folder / "fixed", "mass1", "2.0", can_save_state=False,
                           interfaces=("CoSimulation",))}


def causal_sweep(masses, tmp_path, first="mass1"):
    """The oscillator's causal sweep over two steps, 0..1 s, x1 compared: its folder
    and what it said."""
    path = archive_scene(tmp_path / "two.ssp", {
        "mass1": (masses[first], "CoSimulation", ""),
        "mass2": (masses["mass2"], "CoSimulation", "")}, LINKS, stop=1.0, step=0.01,
        master='coupling="causal"')
    out = tmp_path / "sweep"
    code = main(["sweep", str(path), "--step", "0.01,0.005", "--columns", "mass1.x1",
                 "--out", str(out)])
    assert code == 0
    with open(out / "sweep.csv", newline="") as file:
        return out, list(csv.DictReader(file))


def test_the_points_are_measured_against_the_reference_run_not_the_tightest(
        masses, tmp_path, capsys):
    """Each point's error is its distance from the closed form, to 1 %: the reference
    run is off by less than 1e-4 of the peak (measured: 7.6e-7 m), the causal points by
    41.8 % (0.01 s) and 19.3 % (0.005 s) of it.  Against the tightest point the 0.005 s
    point's error would read 0."""
    out, rows = causal_sweep(masses, tmp_path)
    said = capsys.readouterr().err
    assert "reference   measured against dsim's reference run (coupling=strong " in said
    assert "step=auto error_tolerance=1e-07" in said
    assert "dsim's reference run" in (out / "sweep.md").read_text()
    reference = read_columns(out / "reference.csv")
    truth_off = np.max(np.abs(reference["mass1.x1"] - exact_x1(reference["time"])))
    print(f"reference run: {truth_off:.3g} m off the closed form")
    assert truth_off < 1e-4 * PEAK
    assert np.allclose(np.diff(reference["time"]), 0.005)  # a row at each point's step
    assert (out / "reference.stats.json").is_file()
    assert not (out / "reference.running.csv").exists()
    for row in rows:
        point = read_columns(out / f"point_{int(row['point']):03d}.csv")
        exact = np.max(np.abs(point["mass1.x1"] - exact_x1(point["time"]))) / PEAK
        print(f"step {row['step']}: sweep error {float(row['error']):.4g}, closed form "
              f"{exact:.4g}")
        assert float(row["error"]) == pytest.approx(exact, rel=0.01)
        assert exact > 0.01  # causal, far off: what the tightest point would hide

    # a rerun into the folder reads the reference back instead of running it again
    before = (out / "reference.csv").stat().st_mtime_ns
    out_again, _ = causal_sweep(masses, tmp_path)
    assert (out_again / "reference.csv").stat().st_mtime_ns == before


def test_where_the_reference_run_cannot_be_made_the_tightest_point_is_and_it_says_why(
        masses, tmp_path, capsys):
    """mass1 cannot save its state: no step auto, so the tightest point (0.005 s) is the
    reference and the other point's error is measured against it."""
    out, rows = causal_sweep(masses, tmp_path, first="fixed")
    said = capsys.readouterr().err
    assert "did not complete" in said and "cannot" in said
    assert "measuring against the tightest point instead" in said
    assert not (out / "reference.csv").exists()
    assert not (out / "reference.running.csv").exists()
    errors = {row["step"]: float(row["error"]) for row in rows}
    assert errors["0.005"] == 0.0 and errors["0.01"] > 0.0
    assert "the tightest point (step=0.005)" in (out / "sweep.md").read_text()
