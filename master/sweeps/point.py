"""One point of a sweep as ``dsim sweep`` runs it in this process
(:func:`dsim.master.sweeps.sweep.run_point`) and a Ray worker runs it
(:mod:`dsim.master.sweeps.ray_points`): the keywords of its run (:func:`keywords`) and how it
ran (:class:`PointRun`), here so that neither of those two modules imports the other."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from dsim.master.sweeps.design import split


@dataclass
class PointRun:
    """How one point ran: its :class:`~dsim.master.recording.results.RunResult` (None
    for bad input), the problems of bad input, wall seconds and where its results are."""

    result: object = None
    problems: list = field(default_factory=list)
    wall_seconds: float = math.nan
    results: Path | None = None


def keywords(configuration: dict) -> dict:
    """The keywords of ``dsim.simulate``/``prepare`` for a point: its settings, and its
    model parameters as ``parameters`` (left out when there are none)."""
    settings, parameters = split(configuration)
    return {**settings, "parameters": parameters} if parameters else settings
