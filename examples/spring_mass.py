"""Seed section 5.3.1: two spring-mass subsystems glued by a flexible joint,
against the monolithic model of eq. 5.37.

Monolithic reference (eq. 5.37): masses m1, m2, m3 in one chain, m1 on a spring
k to ground, the joint law between m1 and m2, a spring k between m2 and m3, a
constant force F on m3; integrated with the same trapezoidal rule and step (the
scene's twin, :mod:`dsim.build_fmus.twins.spring_mass`).

``python -m examples.spring_mass`` runs both scenes, prints the difference and
writes a PNG; ``--results FILE.csv`` compares a finished run instead.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dsim.build_fmus.twins.spring_mass import monolithic

ROOT = Path(__file__).resolve().parent.parent


def compare(csv_path, nonlinear: bool) -> dict:
    """Largest difference of m3's position between a glued run and the reference,
    absolute (m) and relative to the reference's peak |x3|."""
    from dsim.master.recording.results import read_csv

    header, data = read_csv(csv_path)
    times = data[:, 0]
    glued = data[:, header.index("right.x[2]")]
    step = times[1] - times[0]
    ref_times, positions = monolithic(nonlinear, stop=times[-1], step=step)
    reference = np.interp(times, ref_times, positions[:, 2])
    peak = float(np.max(np.abs(reference)))
    error = float(np.max(np.abs(glued - reference)))
    return {"error": error, "peak": peak, "relative_error": error / peak,
            "times": times, "glued": glued, "reference": reference}


def main(nonlinear: bool = True, plot: bool = False, out_dir=ROOT / "results") -> dict:
    """Run the glued scene through dsim and compare it with the reference."""
    from dsim.master.api import simulate

    name = "spring_mass_nonlinear" if nonlinear else "spring_mass_linear"
    csv_path = Path(out_dir) / f"{name}.csv"
    statistics = simulate(ROOT / "build" / "ssp" / f"{name}.ssp", out=csv_path)
    result = compare(csv_path, nonlinear)
    result["statistics"] = statistics.statistics
    if plot:
        plot_comparison(result, Path(out_dir) / f"{name}_vs_monolithic.png", name)
    return result


def plot_comparison(result: dict, png: Path, title: str) -> None:
    """Glued and monolithic x3 over each other, and their difference."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dsim.master.recording.results import save_figure

    figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
    top.plot(result["times"], result["reference"], "k-", lw=2.5, label="monolithic (eq. 5.37)")
    top.plot(result["times"], result["glued"], "C1--", label="glued (dsim, 2 FMUs)")
    top.set_ylabel("x3 (m)")
    top.legend()
    top.set_title(title)
    bottom.semilogy(result["times"], np.abs(result["glued"] - result["reference"]) + 1e-20)
    bottom.set_ylabel("|glued - monolithic| (m)")
    bottom.set_xlabel("time (s)")
    for axis in (top, bottom):
        axis.grid(True, alpha=0.3)
    save_figure(figure, png)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--linear", action="store_true", help="the linear joint scene")
    parser.add_argument("--results", help="compare this finished run's CSV")
    args = parser.parse_args()
    nonlinear = not args.linear
    if args.results:
        result = compare(args.results, nonlinear)
        png = Path(args.results).with_name(Path(args.results).stem + "_vs_monolithic.png")
        plot_comparison(result, png, Path(args.results).stem)
    else:
        result = main(nonlinear, plot=True)
        png = ROOT / "results" / "spring_mass_vs_monolithic.png"
    print(f"glued vs monolithic (eq. 5.37): max |x3 difference| = {result['error']:.3e} m "
          f"= {result['relative_error']:.2e} of peak |x3| ({result['peak']:.4f} m); "
          f"plot {png}")
