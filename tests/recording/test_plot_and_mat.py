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
