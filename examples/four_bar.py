"""Seed section 5.3.2: the parallelogram four bar glued from three FMUs through
its singular (collinear) configurations, against the whole mechanism in one
:class:`~dsim.fmus.linkage.core.Linkage` (the scenes' twins,
:mod:`dsim.build_fmus.twins.four_bar`).

The monolithic references, one per scene (fixed, penalized, flexible joints), and
what each solves, are described in :mod:`dsim.build_fmus.twins.four_bar`.  Forces on the
coupler at A compare with the CSV's ``A.f_x``, ``A.f_y`` (port b of joint A is
coupler.A).

``python -m examples.four_bar [--joints fixed|penalized|flexible] [--tol 1e-8]`` runs
the glued scene, prints the differences and writes a PNG into results/; a fixed run
that fails at the singular point is reported with its converged part.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from dsim.build_fmus.linkage_scenes import FOUR_BAR
from dsim.build_fmus.twins.four_bar import TWINS, monolithic, whole_model  # noqa: F401

ROOT = Path(__file__).resolve().parent.parent


def compare(csv_path, scene: str) -> dict:
    """Glued (CSV rows of four_bar_singular_<scene>, possibly a failed run's converged
    part) against its twin: largest force difference at A (N) and its ratio to the
    peak, rocker angular velocity difference (rad/s)."""
    from dsim.master.recording.results import read_csv

    header, data = read_csv(csv_path)
    times = data[:, 0]
    reference = monolithic(scene, stop=max(times[-1], FOUR_BAR["step"]))
    count = len(times)
    force = np.column_stack((data[:, header.index("A.f_x")], data[:, header.index("A.f_y")]))
    ref_force = reference["force"][:count]
    rocker = data[:, header.index("rocker.omega")]
    error = np.linalg.norm(force[1:] - ref_force[1:], axis=1)
    peak = float(np.max(np.linalg.norm(reference["force"], axis=1)))
    return {"times": times, "glued_force": np.linalg.norm(force, axis=1),
            "reference_force": np.linalg.norm(ref_force, axis=1),
            "glued_omega": rocker, "reference_omega": reference["omega"][:count, 1],
            "force_error": float(np.max(error, initial=0.0)), "force_peak": peak,
            "force_relative": float(np.max(error, initial=0.0) / peak),
            "omega_error": float(np.max(np.abs(rocker - reference["omega"][:count, 1])))}


def main(joints: str = "flexible", tolerance: float | None = None, plot: bool = False,
         stop: float | None = None, out_dir=ROOT / "results") -> dict:
    """Run four_bar_singular_<joints> through dsim; a failure is part of the result
    (``failure``: the message naming the step and joint)."""
    import dsim

    name = f"four_bar_singular_{joints}"
    csv_path = Path(out_dir) / f"{name}.csv"
    run = dsim.simulate(ROOT / "build" / "ssp" / f"{name}.ssp", out=csv_path,
                        tolerance=tolerance, stop=stop)
    result = compare(csv_path, joints)
    result["failure"] = run.message if run.status == "failed" else None
    if plot:
        plot_comparison(result, Path(out_dir) / f"{name}_vs_monolithic.png", name)
    return result


def plot_comparison(result: dict, png: Path, title: str) -> None:
    """Force magnitude at A and rocker angular velocity, glued over monolithic."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dsim.master.recording.results import save_figure

    figure, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    t = result["times"]
    for axis, key, label in zip(axes, ("force", "omega"), ("|F_A| (N)", "rocker omega (rad/s)")):
        axis.plot(t, result[f"reference_{key}"], "k-", lw=2.5, label="monolithic (one Linkage)")
        axis.plot(t, result[f"glued_{key}"], "C1--", label="glued (dsim, 3 FMUs)")
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
    axes[0].legend()
    axes[0].set_title(title + (f" -- {result['failure']}" if result.get("failure") else ""),
                      fontsize=8 if result.get("failure") else None)
    axes[-1].set_xlabel("time (s)")
    save_figure(figure, png)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--joints", choices=sorted(TWINS), default="flexible")
    parser.add_argument("--tol", type=float, help="interface tolerance, m")
    parser.add_argument("--stop", type=float)
    args = parser.parse_args()
    result = main(args.joints, args.tol, plot=True, stop=args.stop)
    if result["failure"]:
        print(f"glued run failed: {result['failure']}")
    print(f"glued vs monolithic: |F_A| difference {result['force_error']:.3e} N = "
          f"{result['force_relative']:.2e} of the peak {result['force_peak']:.4g} N; "
          f"rocker omega {result['omega_error']:.3e} rad/s")
