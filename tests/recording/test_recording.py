"""What a run records: ``outputs`` (globs over the columns) and ``output_interval``
(every k-th macro step, exact grid points, the last converged step kept); the CSV,
the in-memory result and the plot honour both, and the values are the full run's."""
import json

import numpy as np
import pytest

import dsim
from dsim.master.recording.results import read_columns
from dsim.master.tools.cli import main


def test_outputs_choose_the_columns_of_the_csv_the_result_and_the_plot(built, tmp_path):
    scene = built["ssp"] / "spring_mass_linear.ssp"
    full = dsim.simulate(scene, stop=1.0)
    chosen = dsim.simulate(scene, stop=1.0, outputs=["right.x*", "j1.*"],
                           out=tmp_path / "r.csv", plot=tmp_path / "r.png")
    assert chosen.status == "completed"
    names = ["time", "right.x[1]", "right.x[2]", "j1.f_x"]
    assert (tmp_path / "r.csv").read_text().splitlines()[0] == ",".join(names)
    assert list(chosen.signals) == names
    for name in names:  # the same numbers, to the last bit
        assert np.array_equal(chosen[name], full[name])
    assert (tmp_path / "r.png").stat().st_size > 1000
    # a column's own name with brackets is a name, not a glob class
    exact = dsim.simulate(scene, stop=0.1, outputs="right.x[2]")
    assert list(exact.signals) == ["time", "right.x[2]"]
    memory = dsim.simulate(scene, stop=1.0, outputs=["left.*"])
    assert list(memory.signals) == ["time", "left.x[1]"]
    assert np.array_equal(memory["left.x[1]"], full["left.x[1]"])


def test_outputs_plot_and_kpis_read_a_column_pattern_alike(built, tmp_path, capsys):
    """One rule for a column pattern everywhere: * and ? are wildcards, brackets are
    part of the names (``right.x[*]`` is every right.x, ``x[12]`` no class of 1 or 2)."""
    from dsim.master.sweeps.kpi import parse

    scene = built["ssp"] / "spring_mass_linear.ssp"
    result = dsim.simulate(scene, stop=0.1, outputs="right.x[*]", out=tmp_path / "r.csv")
    assert list(result.signals) == ["time", "right.x[1]", "right.x[2]"]
    assert parse("maxabs(right.x[*])").columns(result.signals) == ["right.x[1]", "right.x[2]"]
    assert main(["plot", str(tmp_path / "r.csv"), "right.x[*]", "--out",
                 str(tmp_path / "r.png")]) == 0
    assert "2 signals of 1 results" in capsys.readouterr().out
    assert main(["run", str(scene), "--stop", "0.1", "--outputs", "right.x[12]",
                 "--out", str(tmp_path / "s.csv")]) == 2
    assert "outputs: pattern 'right.x[12]' matches no recorded column" in capsys.readouterr().err
    assert parse("max(right.x[12])").columns(result.signals) == []


def test_output_interval_records_exact_grid_points_and_the_last_step(built, tmp_path):
    scene = built["ssp"] / "spring_mass_linear.ssp"
    full = dsim.simulate(scene, stop=1.0)
    coarse = dsim.simulate(scene, stop=1.0, output_interval=0.03, out=tmp_path / "c.csv")
    steps = np.r_[np.arange(0, 101, 3), 100]  # every 3rd step, and the stop time
    assert len(coarse["time"]) == len(steps) == 35
    assert coarse["time"][-2:].tolist() == [full["time"][99], 1.0]
    for name in full.signals:
        assert np.array_equal(coarse[name], full[name][steps]), name
    on_file = read_columns(tmp_path / "c.csv")
    assert np.array_equal(on_file["right.x[2]"], full["right.x[2]"][steps])
    statistics = json.loads((tmp_path / "c.stats.json").read_text())
    assert statistics["recording"] == {"outputs": [], "output_interval": 0.03,
                                       "every_steps": 3}
    assert statistics["steps"] == 100  # every step ran; a third of them were recorded


def test_a_failed_run_keeps_its_last_converged_step(built, tmp_path):
    failed = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", max_iterations=2,
                           step_cuts=0, output_interval=0.5, out=tmp_path / "f.csv")
    assert failed.status == "failed" and failed.steps % 50 != 0
    times = read_columns(tmp_path / "f.csv")["time"]
    assert times[-1] == failed.time and len(times) == failed.steps // 50 + 2


@pytest.mark.parametrize("arguments,expected", [
    (["--output-interval", "0.015"], "output_interval 0.015 s is not a whole multiple of the "
                                     "macro step 0.01 s: rows are recorded only where the "
                                     "master lands (try 0.01 or 0.02 s)"),
    (["--output-interval", "-1"], "output_interval must be a finite number greater than 0"),
    (["--output-interval", "0.005"], "not a whole multiple of the macro step 0.01 s"),
    (["--outputs", "rigth.x*"], "outputs: pattern 'rigth.x*' matches no recorded column "
                                "(closest: right.x[2]"),
])
def test_a_bad_choice_is_one_line_and_exit_2(built, tmp_path, capsys, arguments, expected):
    out = tmp_path / "r.csv"
    code = main(["run", str(built["ssp"] / "spring_mass_linear.ssp"), *arguments, "--out",
                 str(out), "--quiet"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and expected in lines[0], lines
    assert list(tmp_path.iterdir()) == []


def test_outputs_choose_string_columns_too(block_fmus, tmp_path):
    from tests.support.scene_files import component, scene_folder, ssd

    folder = scene_folder(tmp_path / "one", ssd("one", [component("b", "resources/b.fmu")],
                                                 stop=0.05), {"b.fmu": block_fmus["state"]})
    every = dsim.simulate(folder)
    assert {"b.y", "b.count", "b.positive", "b.status"} <= set(every.signals)
    chosen = dsim.simulate(folder, outputs=["b.st*", "b.y"], output_interval=0.02,
                           out=tmp_path / "b.csv")
    assert list(chosen.signals) == ["time", "b.y", "b.status"]
    assert chosen["b.status"].tolist() == ["block::0", "block::2", "block::4", "block::5"]
    assert (tmp_path / "b.csv").read_text().splitlines()[0] == "time,b.y,b.status"
