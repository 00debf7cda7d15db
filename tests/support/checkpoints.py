"""What the checkpoint tests share (docs/checkpoints.md): statistics without what a
clock measured, a run with checkpoints, and a sweep from one checked on a backend."""
from __future__ import annotations

import json
from pathlib import Path

import dsim


def timeless(statistics):
    """The statistics without what a clock measured and what says how the run went
    on (checkpoints written, the checkpoint resumed from)."""
    if isinstance(statistics, dict):
        return {k: timeless(v) for k, v in statistics.items()
                if "seconds" not in k and k not in ("phases", "checkpoints", "resumed")}
    if isinstance(statistics, list):
        return [timeless(v) for v in statistics]
    return statistics


def checkpoints_of(built, tmp_path, **settings) -> Path:
    """A run of spring_mass_nonlinear to 1 s with a checkpoint every 0.25 s, all kept:
    its checkpoint folder."""
    result = dsim.simulate(built["ssp"] / "spring_mass_nonlinear.ssp", stop=1.0,
                           out=tmp_path / "run.csv", checkpoint_every=0.25,
                           checkpoint_keep=10, handle_signals=False, **settings)
    assert result.status == "completed"
    return tmp_path / "run.checkpoints"


def sweep_from_checkpoint(built, tmp_path, capsys, backend: str) -> None:
    """``dsim sweep --from`` on ``backend``: run to 1 s once, then two tolerances from
    its last checkpoint (0.75 s) to 1.5 s; each point's rows start there with the
    checkpoint's state (the same first row)."""
    from dsim.master.tools.cli import main

    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    folder = checkpoints_of(built, tmp_path)
    first = (tmp_path / "run.csv").read_text().splitlines()[76]  # the row at 0.75 s
    out = tmp_path / "sweep"
    assert main(["sweep", str(scene), "--from", str(folder), "--stop", "1.5", "--tolerance",
                 "1e-6,1e-9", "--out", str(out), "--backend", backend]) == 0, \
        capsys.readouterr().err
    for point in ("point_001", "point_002"):
        rows = (out / f"{point}.csv").read_text().splitlines()
        assert rows[1] == first and rows[-1].startswith("1.5,")
        started = json.loads((out / f"{point}.stats.json").read_text())["started_from"]
        assert started["time"] == 0.75
