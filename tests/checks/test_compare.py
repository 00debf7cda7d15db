"""`dsim compare`: the regression check a CI job runs on a results CSV."""
import numpy as np

from dsim.master.tools.cli import main
from tests.support.results import write_csv as write


def test_same_run_passes_and_a_drift_fails(tmp_path, capsys):
    times = np.linspace(0, 1, 101)
    write(tmp_path / "ref.csv", times, {"a.x": np.sin(times), "j.f_x": np.cos(times)})
    write(tmp_path / "same.csv", times, {"a.x": np.sin(times) + 1e-9, "j.f_x": np.cos(times)})
    assert main(["compare", str(tmp_path / "same.csv"), str(tmp_path / "ref.csv"),
                 "--rtol", "1e-6"]) == 0
    write(tmp_path / "drift.csv", times, {"a.x": np.sin(times) + 1e-3 * times,
                                          "j.f_x": np.cos(times)})
    assert main(["compare", str(tmp_path / "drift.csv"), str(tmp_path / "ref.csv")]) == 1
    out = capsys.readouterr()
    assert "a.x" in out.out and "DIFFERS" in out.out and "1 of 2 columns" in out.err


def test_other_time_grid_is_interpolated(tmp_path):
    fine, coarse = np.linspace(0, 1, 1001), np.linspace(0, 1, 11)
    write(tmp_path / "ref.csv", fine, {"a.x": 2 * fine})
    write(tmp_path / "run.csv", coarse, {"a.x": 2 * coarse})
    assert main(["compare", str(tmp_path / "run.csv"), str(tmp_path / "ref.csv"),
                 "--rtol", "1e-12"]) == 0


def test_bad_files_are_input_errors(tmp_path, capsys):
    write(tmp_path / "ref.csv", [0.0, 1.0], {"a.x": [0.0, 1.0]})
    (tmp_path / "junk.csv").write_text("not,a\nresult,file\n")
    assert main(["compare", str(tmp_path / "missing.csv"), str(tmp_path / "ref.csv")]) == 2
    assert main(["compare", str(tmp_path / "junk.csv"), str(tmp_path / "ref.csv")]) == 2
    assert main(["compare", str(tmp_path / "ref.csv"), str(tmp_path / "ref.csv"),
                 "--columns", "b.y"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 3 and "missing.csv: no such file" in lines[0]
