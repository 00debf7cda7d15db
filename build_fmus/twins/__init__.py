"""Monolithic twins as results files: the same columns a glued run records, computed
by each scene's monolithic reference (the modules of this package, and
:func:`dsim.fmus.elastic.frame.monolithic_frame`) at a tenth of the scene's step.

``dsim build-fmus`` packs them into the scenes as ``resources/reference.csv``, which
``dsim sweep`` measures its points against by default (docs/sweep.md): a run's error
against it is the gluing error plus the time discretization's, what a user trading
step size for speed needs to see.  At a tenth of the step the twin's own
discretization error is a hundredth of a run's at the scene's step (the rules are
second order).  ``python -m dsim.build_fmus.twins SCENE --out FILE.csv`` writes one.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dsim.build_fmus.linkage_scenes import FOUR_BAR
from dsim.build_fmus.scenes import CHAIN, SPRING_MASS
from dsim.build_fmus.twins import chain, four_bar, spring_mass
from dsim.fmus.elastic.frame import STEP_SIZE, STOP_TIME, monolithic_frame
from dsim.master.recording.output_files import write_whole

#: the twin's step as a fraction of the scene's
REFINEMENT = 10
#: the frame scenes' recorded load-point displacement (examples/frame.py compares it)
FRAME_OUTPUT = "cross_front.load.u_x"


def _spring_mass(nonlinear: bool) -> dict:
    times, x = spring_mass.monolithic(nonlinear, step=SPRING_MASS["step"] / REFINEMENT)
    return {"time": times, "left.x[1]": x[:, 0], "right.x[1]": x[:, 1], "right.x[2]": x[:, 2]}


def _chain(n: int) -> dict:
    times, x = chain.monolithic(n, step=CHAIN["step"] / REFINEMENT)
    return {"time": times, **{f"m{i}.x[1]": x for i in range(1, n + 1)}}


def four_bar_twin(scene: str, refinement: int = REFINEMENT,
                  spectral_radius: float | None = None) -> dict:
    """The twin of four_bar_singular_<scene> (``fixed``, ``penalized`` or ``flexible``;
    build_fmus/twins/four_bar.py) at the scene's step divided by ``refinement``, its rule's
    spectral radius overridden by ``spectral_radius``: the columns a glued run records."""
    r = four_bar.monolithic(scene, step=FOUR_BAR["step"] / refinement,
                   spectral_radius=spectral_radius)
    return {"time": r["times"], "crank.omega": r["omega"][:, 0], "rocker.omega": r["omega"][:, 1],
            "A.f_x": r["force"][:, 0], "A.f_y": r["force"][:, 1]}


def _frame() -> dict:
    r = monolithic_frame(step_size=STEP_SIZE / REFINEMENT, stop_time=STOP_TIME)
    return {"time": r.time, FRAME_OUTPUT: r.load_u_x}


#: scene -> its twin's columns (name -> values, one per twin step); the other scenes'
#: twins are too slow to compute at every build (crank_slider_*) or too large to ship
#: (chain_100, chain_1000: a column per mass)
TWINS = {
    "spring_mass_linear": lambda: _spring_mass(False),
    "spring_mass_nonlinear": lambda: _spring_mass(True),
    "chain_10": lambda: _chain(10),
    "four_bar_singular_flexible": lambda: four_bar_twin("flexible"),
    # the whole four bar's own Newton loses the singular point at smaller steps (docs/
    # linkages.md): its twin stays at the scene's step
    "four_bar_singular_fixed": lambda: four_bar_twin("fixed", 1),
    "four_bar_singular_penalized": lambda: four_bar_twin("penalized", 1),
    "frame_split": _frame,
}


def twin_csv(scene: str) -> bytes:
    """The twin of ``scene`` as CSV text (dsim's results format: a header, then one row
    per step, numbers in full precision)."""
    columns = TWINS[scene]()
    header = ",".join(columns)
    rows = np.column_stack(list(columns.values()))
    lines = [header] + [",".join(repr(float(v)) for v in row) for row in rows]
    return ("\n".join(lines) + "\n").encode()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("scene", choices=sorted(TWINS))
    parser.add_argument("--out", type=Path, required=True, help="CSV file to write")
    args = parser.parse_args(argv)
    write_whole(args.out, twin_csv(args.scene))
    print(f"wrote {args.out}")
    return 0

