"""The execution engine as a Python caller meets it: dsim.simulate and its result,
settings checked in one place, an execution stepped, watched and stopped, and
the registries of couplings, predictors, refresh policies and backends."""
import json
import math

import numpy as np
import pytest

import dsim
from dsim.master.tools.cli import main


def test_simulate_returns_signals_statistics_and_files(built, tmp_path):
    scene = built["ssp"] / "spring_mass_linear.ssp"
    memory = dsim.simulate(scene, stop=0.5)
    assert memory.status == "completed" and memory.ok and memory.exit_code == 0
    assert memory.steps == 50 and memory.time == 0.5 and memory.files == {}
    assert list(memory.signals) == ["time", "left.x[1]", "right.x[1]", "right.x[2]",
                                    "right.a[2]", "j1.f_x"]
    assert np.allclose(memory["time"], np.arange(51) * 0.01, rtol=0, atol=1e-15)
    stats = memory.statistics
    assert stats["iterations"]["mean_per_step"] == pytest.approx(2.0)
    assert stats["components"]["left"]["do_steps"] == 2 * 50 + 1  # + one perturbation
    assert stats["components"]["left"]["state_saves"] == 50
    assert stats["coupling"] == "iterative" and stats["backend"] == "in-process"
    on_disk = dsim.simulate(scene, stop=0.5, out=tmp_path / "run.csv")
    assert on_disk.files == {"csv": tmp_path / "run.csv",
                             "statistics": tmp_path / "run.stats.json"}
    for name, values in memory.signals.items():  # the CSV holds the same doubles
        assert np.array_equal(on_disk[name], values)
    assert json.loads((tmp_path / "run.stats.json").read_text())["status"] == "completed"


def test_a_failed_run_is_a_result_too(built, tmp_path):
    result = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", max_iterations=2,
                           step_cuts=0, out=tmp_path / "failed.csv")
    assert result.status == "failed" and result.exit_code == 1
    assert "joint 'j1' (j1.f_x) did not converge in 2 iterations" in result.message
    assert isinstance(result.error, dsim.SimulationError)
    assert result.error.step == result.steps + 1  # the step that failed, after the kept ones
    assert len(result["time"]) == result.steps + 1 and result.time == result["time"][-1]
    assert result.statistics["status"] == "failed"


@pytest.mark.parametrize("settings, expected", [
    (dict(tolerance=-1e-9), "setting tolerance must be a finite number greater than 0"),
    (dict(tolerance=0), "setting tolerance must be a finite number greater than 0"),
    (dict(tolerance=math.nan), "setting tolerance must be a finite number greater than 0"),
    (dict(step=0.0), "setting step must be a finite number greater than 0"),
    (dict(step=math.inf), "setting step must be a finite number greater than 0"),
    (dict(stop=math.inf), "setting stop must be a finite number greater than 0"),
    (dict(stop=-1.0), "setting stop must be a finite number greater than 0"),
    (dict(max_iterations=0), "setting max_iterations must be at least 1"),
    (dict(max_iterations=2.5), "setting max_iterations '2.5' is not an integer"),
    (dict(relative_tolerance=-1), "setting relative_tolerance must be a finite number >= 0"),
    (dict(coupling="sideways"),
     "setting coupling 'sideways' is not one of: iterative, explicit, causal, strong"),
    (dict(predictor="cubic"),
     "setting predictor 'cubic' is not one of: none, constant, linear, quadratic"),
    (dict(refresh="sometimes"),
     "setting refresh 'sometimes' is not one of: adaptive, iterations, step"),
    (dict(convergence="soon"), "setting convergence 'soon' is not one of: residual, forces"),
    (dict(start="moving"), "setting start 'moving' is not one of: auto, consistent, rest"),
    (dict(backend="cloud"), "setting backend 'cloud' is not one of: in-process, ray, isolated"),
    (dict(tolerence=1e-9), "unknown setting 'tolerence'"),
    (dict(stop=1e300), "steps of 0.01 s from 0 to 1e+300 s: more than 4.5e+15"),
])
def test_an_invalid_setting_is_bad_input_that_says_what_is_valid(built, settings, expected):
    with pytest.raises(dsim.InputError) as caught:
        dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", **settings)
    assert len(caught.value.problems) == 1 and expected in caught.value.problems[0]


def test_every_invalid_setting_is_listed_at_once(built):
    with pytest.raises(dsim.InputError) as caught:
        dsim.prepare(built["ssp"] / "spring_mass_linear.ssp", tolerance=-1, coupling="x",
                     step=math.nan)
    assert len(caught.value.problems) == 3


def test_the_annotation_the_command_line_and_the_api_check_a_setting_alike(
        built, tmp_path, capsys):
    from tests.support.scenes import archive_with

    bad = archive_with(tmp_path, built, replace=[('tolerance="1e-10"', 'tolerance="-1"')])
    with pytest.raises(dsim.InputError) as caught:
        dsim.prepare(bad)
    assert "glue:Master: tolerance must be a finite number greater than 0, got -1" in \
        caught.value.problems[0]
    scene = str(built["ssp"] / "spring_mass_linear.ssp")
    assert main(["run", scene, "--tol", "-1", "--out", str(tmp_path / "o.csv")]) == 2
    assert main(["run", scene, "--coupling", "sideways", "--out", str(tmp_path / "o.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == ["dsim: error: setting tolerance must be a finite number greater than 0, "
                     "got -1",
                     "dsim: error: setting coupling 'sideways' is not one of: iterative, "
                     "explicit, causal, strong"]
    assert not (tmp_path / "o.csv").exists()


class Watcher(dsim.Observer):
    """Records what an observer sees; stops the run at a given step."""

    def __init__(self, stop_at=None):
        self.records, self.info, self.result, self.stop_at = [], None, None, stop_at
        self.execution = None
        self.files = {}

    def started(self, info):
        self.info = info

    def stepped(self, record):
        self.records.append(record)
        if self.stop_at is not None and record.index == self.stop_at:
            self.execution.stop("enough")

    def finished(self, result):
        self.result = result


def test_an_execution_is_stepped_watched_and_stopped(built):
    plan = dsim.prepare(built["ssp"] / "spring_mass_nonlinear.ssp", stop=1.0)
    watcher = Watcher()
    execution = dsim.Execution(plan, [watcher])
    execution.start()
    assert watcher.info.columns[-1] == "j1.f_x" and watcher.info.planned_steps == 100
    for _ in range(10):
        assert execution.step()
    assert execution.time == pytest.approx(0.1) and execution.index == 10
    execution.stop("the caller had seen enough")
    assert not execution.step()
    result = execution.finish()
    assert result.status == "interrupted" and result.steps == 10
    assert "the caller had seen enough (stopped at t = 0.1 s, step 10 of 100)" in \
        result.message
    assert [r.index for r in watcher.records] == list(range(11))
    assert watcher.result is result
    assert sum(r.iterations for r in watcher.records) == \
        result.statistics["iterations"]["total"]


def test_an_observer_can_stop_the_run(built):
    plan = dsim.prepare(built["ssp"] / "spring_mass_linear.ssp")
    watcher = Watcher(stop_at=7)
    watcher.execution = dsim.Execution(plan, [watcher])
    result = watcher.execution.run(handle_signals=False)
    assert result.status == "interrupted" and result.steps == 7
    assert result.statistics["status"] == "interrupted"


def test_registries_name_the_implementations():
    assert set(dsim.COUPLINGS) == {"iterative", "explicit", "causal", "strong"}
    assert set(dsim.PREDICTORS) == {"none", "constant", "linear", "quadratic"}
    assert set(dsim.REFRESH_POLICIES) == {"adaptive", "iterations", "step"}
    assert set(dsim.CONVERGENCE_TESTS) == {"residual", "forces"}
    assert set(dsim.BACKENDS) == {"in-process", "ray", "isolated"}
    for coupling in dsim.COUPLINGS.values():
        assert issubclass(coupling, dsim.Coupling)
    for backend in dsim.BACKENDS.values():
        assert issubclass(backend, dsim.Backend)


def test_a_scene_without_joints_runs_with_the_causal_coupling(block_fmus, tmp_path):
    """A ring of C blocks, no joints: no Newton, no state saved, one doStep per FMU
    per step; the outputs follow the blocks' exact update (Jacobi, inputs from the
    outputs at the step start)."""
    from benchmarks.causal_benchmark import recurrence
    from tests.support.third_party.build import causal_ring_ssp

    ssp = causal_ring_ssp(tmp_path / "ring.ssp", block_fmus["nostate"], 3, stop=0.2,
                          step=1e-3)
    result = dsim.simulate(ssp)
    assert result.status == "completed" and result.statistics["coupling"] == "causal"
    for component in result.statistics["components"].values():
        assert component["do_steps"] == 200 and component["state_saves"] == 0
        assert set(component["functions"]) >= {"fmi2SetReal", "fmi2DoStep", "fmi2GetReal"}
    outputs = np.column_stack([result[f"b{i}.y"][1:] for i in (1, 2, 3)])
    assert np.max(np.abs(outputs - recurrence(3, 200, False))) < 1e-14


def test_the_causal_coupling_cannot_glue_joints(built):
    with pytest.raises(dsim.InputError, match="coupling 'causal' cannot glue the scene's 1 "
                                              "joints: use iterative or explicit"):
        dsim.prepare(built["ssp"] / "spring_mass_linear.ssp", coupling="causal")
