"""Seed section 2.2.1 (SCENES.md frame_split): a ladder frame split into five
finite-element FMUs (two rails, three cross members) glued node to node on its six
interface edges, against the same frame meshed as one body.

Monolithic reference: :func:`dsim.fmus.elastic.frame.monolithic_frame`, the frame as one
plane-stress mesh (nodes shared on the interfaces), the same Newmark average-acceleration
rule and step H = 1e-4 s. The seed reports no difference beyond round-off (Fig. 2.11):
glued and monolithic load-point displacement agree to 1e-8 of the peak.

``python -m examples.frame`` runs both (0 to 0.2 s), prints the difference and writes
results/frame_split_vs_monolithic.png; ``--stop`` shortens the run.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dsim.build_fmus.twins import FRAME_OUTPUT as OUTPUT
from dsim.fmus.elastic.frame import STEP_SIZE, STOP_TIME, monolithic_frame

ROOT = Path(__file__).resolve().parent.parent


def compare(csv_path, reference=None) -> dict:
    """Largest difference of the load-point x displacement between a glued run and the
    monolithic frame, absolute (m) and relative to the reference's peak; interface forces."""
    from dsim.master.recording.results import read_csv

    header, data = read_csv(csv_path)
    times = data[:, 0]
    glued = data[:, header.index(OUTPUT)]
    if reference is None:
        reference = monolithic_frame(step_size=times[1] - times[0], stop_time=times[-1])
    if reference.time.shape != times.shape or not np.allclose(reference.time, times):
        raise ValueError("the glued run and the reference have different time grids")
    peak = float(np.max(np.abs(reference.load_u_x)))
    error = float(np.max(np.abs(glued - reference.load_u_x)))
    forces = {name: data[:, i] for i, name in enumerate(header) if ".f_" in name}
    return {"error": error, "peak": peak, "relative_error": error / peak, "times": times,
            "glued": glued, "reference": reference.load_u_x, "forces": forces,
            "monolithic_seconds": reference.wall_time}


def main(plot: bool = False, stop: float = STOP_TIME, out_dir=ROOT / "results") -> dict:
    """Run build/ssp/frame_split.ssp through dsim and compare it with the monolithic frame."""
    from dsim.master.api import simulate

    csv_path = Path(out_dir) / "frame_split.csv"
    statistics = simulate(ROOT / "build" / "ssp" / "frame_split.ssp", out=csv_path, stop=stop)
    result = compare(csv_path, monolithic_frame(step_size=STEP_SIZE, stop_time=stop))
    result["statistics"] = statistics.statistics
    if plot:
        plot_comparison(result, Path(out_dir) / "frame_split_vs_monolithic.png")
    return result


def plot_comparison(result: dict, png: Path) -> None:
    """Load-point response glued over monolithic, their difference, and the interface
    forces of the front cross member's joints (node 3, the edge middles)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dsim.master.recording.results import save_figure

    times = result["times"]
    figure, (top, middle, bottom) = plt.subplots(3, 1, sharex=True, figsize=(8, 8))
    top.plot(times, 1e6 * result["reference"], "k-", lw=2.5, label="monolithic (one mesh)")
    top.plot(times, 1e6 * result["glued"], "C1--", label="glued (dsim, 5 FE FMUs)")
    top.set_ylabel("load point u_x (um)")
    top.set_title("frame_split: F_x = 1000 sin(50 pi t) N at (0.05, 0.6) m")
    top.legend(loc="upper left")
    middle.semilogy(times, np.abs(result["glued"] - result["reference"]) + 1e-25)
    middle.set_ylabel("|glued - monolithic| (m)")
    for name in ("front_left[3].f_x", "front_left[3].f_y", "front_right[3].f_x",
                 "front_right[3].f_y", "mid_left[3].f_y", "rear_left[3].f_y"):
        if name in result["forces"]:
            bottom.plot(times, result["forces"][name], label=name)
    bottom.set_ylabel("interface force (N)")
    bottom.set_xlabel("time (s)")
    bottom.legend(fontsize=7, ncol=2, loc="upper left")
    for axis in (top, middle, bottom):
        axis.grid(True, alpha=0.3)
    save_figure(figure, png)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--stop", type=float, default=STOP_TIME, help="stop time, s")
    args = parser.parse_args()
    result = main(plot=True, stop=args.stop)
    stats = result["statistics"]
    print(f"glued vs monolithic: max |u_x difference| = {result['error']:.3e} m "
          f"= {result['relative_error']:.2e} of the peak ({result['peak']:.4e} m)")
    print(f"glued {stats['wall_seconds']:.2f} s ({stats['iterations']['mean_per_step']:.2f} "
          f"iterations per step, {stats['lambda_refreshes']} Lambda refreshes), monolithic "
          f"{result['monolithic_seconds']:.2f} s; plot "
          f"{ROOT / 'results' / 'frame_split_vs_monolithic.png'}")
