"""Checkpoints across backends (docs/checkpoints.md): a checkpoint written in-process
and resumed on Ray workers (and on isolated ones), and one written on Ray resumed
in-process, give the bytes of the in-process run never stopped, and its statistics
but for where it ran."""
import json

import pytest

import dsim
from tests.support.checkpoints import sweep_from_checkpoint, timeless


@pytest.mark.parametrize("first, then", [("in-process", "ray"), ("ray", "in-process"),
                                         ("in-process", "isolated")])
def test_a_checkpoint_resumes_on_another_backend_to_the_same_bytes(built, ray_local,
                                                                   tmp_path, first, then):
    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    reference = dsim.simulate(scene, stop=1.0, out=tmp_path / "reference.csv",
                              handle_signals=False)
    assert reference.status == "completed"
    out = tmp_path / "run.csv"
    written = dsim.simulate(scene, stop=1.0, out=out, checkpoint_every=0.25,
                            checkpoint_keep=10, backend=first, handle_signals=False)
    assert written.status == "completed" and written.statistics["backend"] == first
    assert out.read_bytes() == (tmp_path / "reference.csv").read_bytes()
    for step in (25, 50, 75):
        resumed = dsim.simulate(resume=tmp_path / "run.checkpoints" / f"step-{step:010d}",
                                backend=then, handle_signals=False)
        assert resumed.status == "completed", resumed.message
        assert resumed.statistics["backend"] == then
        assert out.read_bytes() == (tmp_path / "reference.csv").read_bytes(), step
        statistics = timeless(json.loads(out.with_name("run.stats.json").read_text()))
        expected = timeless(written.statistics)
        # where it ran differs (the backend, its workers, the reads and the state
        # serializations a Ray worker makes of its own, as in a run never stopped):
        # every step, save and restore does not
        for stats in (statistics, expected):
            stats.pop("backend")
            stats["components"] = {name: (c["do_steps"], c["state_saves"],
                                          c["state_restores"])
                                   for name, c in stats["components"].items()}
        assert statistics == expected, step


def test_every_point_of_a_sweep_on_ray_starts_from_the_checkpoint(built, ray_local,
                                                                  tmp_path, capsys):
    """The checkpoint read once by the driver travels to each point's worker."""
    sweep_from_checkpoint(built, tmp_path, capsys, "ray")
