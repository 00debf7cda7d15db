"""Seed section 4.2.1: the crank slider glued from three FMUs, against the whole
mechanism solved as one :class:`~fmus.linkage.core.Linkage`.

Monolithic reference: crank, coupler and slider in one planar multibody model
(revolutes O, A, B, prismatic rail, crank driver), the same trapezoidal rule,
Baumgarte rows (xi = 1, w = 1000 rad/s) and step H = 1e-3 s.  Its reactions
``A.f_x``, ``A.f_y`` are the forces on the coupler at A, which is what port b of
glue joint A (coupler.A) receives, so they compare with the CSV's ``A.f_x``,
``A.f_y`` directly.

The flexible scene (crank_slider_flexible: the coupler a FlexibleLink2D) is
compared with the same *rigid* monolithic model: dsim has no monolithic
floating-frame model of the whole flexible mechanism yet, so its difference is
the coupler's flexibility plus the gluing error, not the gluing error alone.

``python -m examples.crank_slider [--stop 5] [--flexible]`` runs the glued scene
through dsim, prints the differences and writes PNGs into results/.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from build_fmus.linkage_scenes import CRANK_SLIDER
from fmus.linkage.scenes import crank_slider

ROOT = Path(__file__).resolve().parent.parent


def monolithic(stop: float = CRANK_SLIDER["stop"], step: float = CRANK_SLIDER["step"]) -> dict:
    """The whole crank slider, one row per step: times (s), joint A force on the
    coupler (N), coupler angular velocity (rad/s), slider position (m); ``seconds``
    is the wall time of the integration alone."""
    whole = crank_slider("whole")
    whole.initialize(0.0)
    count = round(stop / step)
    force, omega, slider = np.zeros((count + 1, 2)), np.zeros(count + 1), np.zeros(count + 1)
    slider[0] = whole.q[2, 0]
    start = time.perf_counter()
    for n in range(count):
        whole.step(n * step, step)
        r = whole.reactions()
        force[n + 1] = r["A.f_x"], r["A.f_y"]
        omega[n + 1] = whole.v[1, 2]
        slider[n + 1] = whole.q[2, 0]
    return {"times": np.arange(count + 1) * step, "force": force, "omega": omega,
            "slider": slider, "seconds": time.perf_counter() - start}


def compare(csv_path, reference: dict | None = None) -> dict:
    """Glued (CSV) minus monolithic: largest differences of the force at A (vector,
    N), the coupler's angular velocity (rad/s) and the slider position (m), each
    also relative to the reference's peak; the t = 0 row is skipped (the master
    writes zero forces there, the mechanism starts at rest so they are zero)."""
    from master.results import read_csv

    header, data = read_csv(csv_path)
    times = data[:, 0]
    column = {name: data[:, header.index(name)] for name in header}
    if reference is None:
        reference = monolithic(stop=times[-1], step=times[1] - times[0])
    count = len(times)
    force = np.column_stack((column["A.f_x"], column["A.f_y"]))
    ref_force = reference["force"][:count]
    result = {"times": times, "glued_force": np.hypot(*force.T),
              "reference_force": np.hypot(*ref_force.T), "glued_omega": column["coupler.omega"],
              "reference_omega": reference["omega"][:count],
              "glued_slider": column["slider.P.u_x"],
              "reference_slider": reference["slider"][:count]}
    force_error = np.max(np.linalg.norm(force[1:] - ref_force[1:], axis=1))
    force_peak = np.max(result["reference_force"])
    omega_error = np.max(np.abs(result["glued_omega"] - result["reference_omega"]))
    slider_error = np.max(np.abs(result["glued_slider"] - result["reference_slider"]))
    result.update(force_error=float(force_error), force_peak=float(force_peak),
                  force_relative=float(force_error / force_peak),
                  omega_error=float(omega_error),
                  omega_relative=float(omega_error / np.max(np.abs(result["reference_omega"]))),
                  slider_error=float(slider_error))
    return result


def main(flexible: bool = False, plot: bool = False, stop: float | None = None,
         out_dir=ROOT / "results") -> dict:
    """Run crank_slider_rigid (or _flexible) through dsim and compare it with the
    rigid monolithic reference."""
    from master.run import run

    name = "crank_slider_flexible" if flexible else "crank_slider_rigid"
    csv_path = Path(out_dir) / f"{name}.csv"
    statistics = run(ROOT / "build" / "ssp" / f"{name}.ssp", csv_path, stop=stop)
    result = compare(csv_path)
    result["statistics"] = statistics.data
    if plot:
        plot_comparison(result, Path(out_dir) / f"{name}_vs_monolithic.png", name)
    return result


def plot_comparison(result: dict, png: Path, title: str) -> None:
    """Force magnitude at A, coupler angular velocity, slider position: glued over
    monolithic."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 8))
    t = result["times"]
    for axis, key, label in zip(axes, ("force", "omega", "slider"),
                                ("|F_A| (N)", "coupler omega (rad/s)", "slider x (m)")):
        axis.plot(t, result[f"reference_{key}"], "k-", lw=2.5, label="monolithic (one Linkage)")
        axis.plot(t, result[f"glued_{key}"], "C1--", label="glued (dsim, 3 FMUs)")
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
    axes[0].legend()
    axes[0].set_title(title)
    axes[-1].set_xlabel("time (s)")
    figure.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(png, dpi=110)
    plt.close(figure)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--flexible", action="store_true", help="the flexible coupler scene")
    parser.add_argument("--stop", type=float, help="stop time, s (default: the scene's 5 s)")
    args = parser.parse_args()
    result = main(args.flexible, plot=True, stop=args.stop)
    print(f"glued vs monolithic: |F_A| difference {result['force_error']:.3e} N = "
          f"{result['force_relative']:.2e} of the peak {result['force_peak']:.4g} N; coupler "
          f"omega {result['omega_error']:.3e} rad/s; slider {result['slider_error']:.3e} m")
