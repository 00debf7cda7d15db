"""``dsim run/validate/info --input`` from the command line (in process): every bad
table is one line and exit 2, before anything runs (docs/inputs.md)."""
import importlib.util
import shutil

import numpy as np
import pytest

from dsim.master.tools.cli import main

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")

#: file name -> (its text, what its one line says)
BAD = {
    "unknown_component.csv": ("time,slave one.realIn\n0,1\n",
                              "the scene has no component 'slave one' (closest: slave uno)"),
    "unknown_variable.csv": ("time,slave uno.realin\n0,1\n",
                             "has no variable 'realin' (closest: realIn)"),
    "output.csv": ("time,slave uno.realOut\n0,1\n", "is output 'realOut'"),
    "parameter.csv": ("time,slave uno.offset\n0,1\n", "is parameter 'offset'"),
    "string.csv": ("time,slave uno.label\n0,1\n", "is a String input"),
    "backwards.csv": ("time,slave uno.realIn\n0,1\n0.5,2\n0.4,3\n",
                      "line 4: time 0.4 s is before the row above's 0.5 s"),
    "cell.csv": ("time,slave uno.realIn\n0,1\n0.5,abc\n",
                 "line 3, column 'slave uno.realIn': 'abc' is not a number"),
    "nan.csv": ("time,slave uno.realIn\n0,nan\n", "is not a finite number"),
    "empty.csv": ("", "the file is empty"),
    "rows.csv": ("time,slave uno.realIn\n", "the table has no rows"),
    "first.csv": ("t,slave uno.realIn\n0,1\n", "the first column is 't'"),
    "alone.csv": ("time\n0\n", "a time column only"),
    "ragged.csv": ("time,slave uno.realIn\n0,1,2\n", "line 2: 3 cells, the header has 2"),
    "twice.csv": ("time,slave uno.realIn,slave uno.realIn\n0,1,2\n", "is given twice"),
    "fraction.csv": ("time,slave uno.intIn\n0,1.5\n", "row 1 holds 1.5, not a whole number"),
    "boolean.csv": ("time,slave uno.flag\n0,2\n", "row 1 holds 2 (give 0 or 1)"),
    "suffix.txt": ("time,slave uno.realIn\n0,1\n", "an input table is a .csv or .mat file"),
}


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    from tests.support.scenarios import offset_scenes

    return offset_scenes(tmp_path_factory.mktemp("input_cli"))


def _run(capsys, *argv) -> tuple[int, str]:
    code = main(list(argv))
    return code, capsys.readouterr().err


@pytest.mark.parametrize("name", sorted(BAD))
def test_a_bad_table_is_one_line_and_exit_2(scenes, tmp_path, capsys, name):
    text, said = BAD[name]
    path = tmp_path / name
    path.write_text(text)
    out = tmp_path / "run.csv"
    code, err = _run(capsys, "run", str(scenes["single"]), "--input", str(path), "--out",
                     str(out), "--quiet")
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and said in err, err
    assert not out.exists()


def test_a_connected_input_is_refused(scenes, tmp_path, capsys):
    path = tmp_path / "in.csv"
    path.write_text("time,b.realIn\n0,1\n")
    code, err = _run(capsys, "run", str(scenes["chain"]), "--input", str(path), "--out",
                     str(tmp_path / "run.csv"))
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "'b.realIn' is fed by the connection from 'a.realOut'" in err


def test_mat_files_without_time_or_in_version_7_3_are_refused(scenes, tmp_path, capsys):
    from scipy.io import savemat

    savemat(tmp_path / "none.mat", {"x": np.zeros(3)})
    (tmp_path / "v73.mat").write_bytes(b"MATLAB 7.3 MAT-file, Platform: GLNXA64" + b" " * 600)
    said = {"none.mat": "no vector 'time'", "v73.mat": "a MATLAB 7.3 (HDF5) .mat file"}
    if importlib.util.find_spec("h5py") is not None:
        pytest.skip("h5py reads version 7.3 files here")
    for name, text in said.items():
        code, err = _run(capsys, "run", str(scenes["single"]), "--input",
                         str(tmp_path / name), "--out", str(tmp_path / "run.csv"))
        assert code == 2 and len(err.strip().splitlines()) == 1 and text in err, err


def test_info_summarises_the_table_and_validate_takes_it(scenes, tmp_path, capsys):
    path = tmp_path / "in.csv"
    path.write_text("time,slave uno.realIn,slave uno.intIn\n0,0,1\n0.5,1,3\n0.5,2,4\n")
    assert main(["info", str(scenes["single"]), "--input", str(path)]) == 0
    out = capsys.readouterr().out
    assert (f"input table {path}: 3 rows, 2 columns, t = 0 .. 0.5 s (values held outside), "
            "jumps at t = 0.5 s") in out
    assert "slave uno.realIn: 0 .. 2 -> slave uno.realIn (interpolated)" in out
    assert "slave uno.intIn: 1 .. 4 -> slave uno.intIn (held)" in out
    assert "holds the first value before the table's span and the last after it" in out
    assert main(["validate", str(scenes["single"]), "--input", str(path)]) == 0
    assert main(["run", str(scenes["single"]), "--input", str(path), "--quiet", "--out",
                 str(tmp_path / "run.csv")]) == 0


def test_every_sweep_point_runs_with_the_table(scenes, tmp_path, capsys):
    from dsim.master.recording.results import read_columns
    from dsim.master.reading.input_tables import read_table
    from dsim.master.sweeps.sweep import command_line
    from dsim.master.sweeps.table import Point

    path = tmp_path / "in.csv"
    path.write_text("time,slave uno.realIn\n0,0\n1,1\n")
    out = tmp_path / "sweep"
    assert main(["sweep", str(scenes["single"]), "--step", "0.1,0.05", "--input", str(path),
                 "--out", str(out)]) == 0
    for point in sorted(out.glob("point_*.csv")):
        columns = read_columns(point)
        echo, times = columns["slave uno.realInEcho"], columns["time"]
        # the table's value at each step's start: t - h up to 1 s (the ramp), held after
        step = times[2] - times[1]
        assert np.allclose(echo[1:], np.minimum(times[1:] - step, 1.0), atol=1e-12)
    line = command_line("s.ssp", Point({"step": 0.1}), {}, inputs=read_table(path))
    assert line.endswith(f"--input {path}")
