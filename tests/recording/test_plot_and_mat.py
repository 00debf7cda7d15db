"""`dsim plot` (signals of several results overlaid) and results as a MATLAB .mat file."""
import numpy as np
from scipy.io import loadmat

import dsim
from dsim.master.tools.cli import main


def test_a_run_writes_its_results_as_mat_too(built, tmp_path):
    result = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=1.0,
                           out=tmp_path / "run.csv", mat=tmp_path / "run.mat")
    assert result.files["mat"] == tmp_path / "run.mat"
    content = loadmat(tmp_path / "run.mat")
    names = [str(n[0]) for n in content["names"].ravel()]
    assert names == ["left.x[1]", "right.x[1]", "right.x[2]", "right.a[2]", "j1.f_x"]
    assert np.array_equal(content["time"].ravel(), result["time"])
    for i, name in enumerate(names):  # the same doubles as the CSV
        assert np.array_equal(content["data"][:, i], result[name])
    signals = content["signals"][0, 0]
    assert np.array_equal(signals["right_x_2"].ravel(), result["right.x[2]"])


def test_plot_overlays_signals_of_several_results(built, tmp_path, capsys):
    for name in ("spring_mass_linear", "spring_mass_nonlinear"):
        assert main(["run", str(built["ssp"] / f"{name}.ssp"), "--stop", "2", "--quiet",
                     "--out", str(tmp_path / f"{name}.csv")]) == 0
    files = [str(tmp_path / f"{n}.csv") for n in ("spring_mass_linear", "spring_mass_nonlinear")]
    assert main(["plot", *files, "right.x[2]", "j1.*", "--out", str(tmp_path / "x.png")]) == 0
    assert "2 signals of 2 results" in capsys.readouterr().out
    assert (tmp_path / "x.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["plot", *files, "nothing.like.this"]) == 2
    assert main(["plot", *files, "--out", files[0]]) == 2  # never over an input
    err = capsys.readouterr().err.splitlines()
    assert "no column matches nothing.like.this" in err[0]
    assert "would overwrite an input" in err[1]


def test_plot_gives_each_run_its_colour_and_shows_display_units(built, tmp_path):
    """Two runs of the crank slider (--stop 0.05 and 0.1): each curve its own colour,
    the run told by its line style (the runs of one signal were one colour); the
    crank angle, which the FMU declares in rad with displayUnit="deg", drawn in deg
    (value * 180/pi) on an axis labelled so, as the run's own plot draws it; the
    angular velocity (no display unit) stays in rad/s."""
    from dsim.master.recording.results import (in_display_units, overlay_curves,
                                                read_columns, read_display_units,
                                                read_units)
    from dsim.master.tools.plot import overlay_files

    files = []
    for stop in ("0.05", "0.1"):
        files.append(tmp_path / f"run_{stop}.csv")
        assert main(["run", str(built["ssp"] / "crank_slider_rigid.ssp"), "--stop", stop,
                     "--quiet", "--out", str(files[-1])]) == 0
    display = read_display_units(files[1])
    assert display["crank.theta"]["unit"] == "deg" and "crank.omega" not in display
    raw = read_columns(files[1])
    signals, units = in_display_units(raw, read_units(files[1]), display)
    np.testing.assert_allclose(signals["crank.theta"], np.degrees(raw["crank.theta"]),
                               rtol=1e-15)
    assert units["crank.theta"] == "deg" and units["crank.omega"] == "rad/s"
    overlay = overlay_files(files, ["crank.theta", "crank.omega"], tmp_path / "o.png")
    assert overlay.labels == ["angle (deg)", "angular velocity (rad/s)"]
    curves = overlay_curves({"a": raw, "b": raw}, ["crank.theta"])
    assert [c[3]["color"] for c in curves] == ["C0", "C1"]
    assert [c[3]["linestyle"] for c in curves] == ["-", "--"]
