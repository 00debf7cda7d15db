"""Seed section 4.2.1: the crank slider glued from three FMUs, against the whole
mechanism solved as one model.

Monolithic references, each the same trapezoidal rule, Baumgarte rows (xi = 1,
w = 1000 rad/s, the glue joints' penalized measure) and step H = 1e-3 s:

* rigid coupler (crank_slider_rigid): crank, coupler and slider in one planar
  multibody :class:`~dsim.fmus.linkage.core.Linkage` (revolutes O, A, B, prismatic
  rail, crank driver);
* flexible coupler (crank_slider_flexible): crank and slider rigid, the coupler
  the same floating-frame Euler-Bernoulli beam as FlexibleLink2D (6 elements,
  same reference condition), joints A and B as constraint rows, all in one
  :class:`~dsim.fmus.flexible_link.mechanism.FlexibleMechanism` solved by one Newton
  per step (no PIM, no gluing).  The flexible scene is also compared with the
  rigid model, as an informational number: that difference is the coupler's
  flexibility, not a gluing error.

The models' ``A.f_x``, ``A.f_y`` are the forces on the coupler at A, which is
what port b of glue joint A (coupler.A) receives, so they compare with the CSV's
``A.f_x``, ``A.f_y`` directly.

``python -m examples.crank_slider [--stop 5] [--flexible]`` runs the glued scene
through dsim, prints the differences and writes PNGs into results/.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from dsim.build_fmus.linkage_scenes import COUPLER, CRANK_SLIDER
from dsim.fmus.linkage.scenes import crank_slider

ROOT = Path(__file__).resolve().parent.parent


def monolithic(stop: float = CRANK_SLIDER["stop"], step: float = CRANK_SLIDER["step"],
               flexible: bool = False) -> dict:
    """The whole crank slider, one row per step: times (s), joint A force on the
    coupler (N), coupler angular velocity (rad/s), slider position (m); ``seconds``
    is the wall time of the integration alone.  ``flexible``: the coupler is the
    scene's floating-frame beam (:func:`monolithic_flexible`)."""
    if flexible:
        return monolithic_flexible(stop, step)
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


def monolithic_flexible(stop: float = CRANK_SLIDER["stop"],
                        step: float = CRANK_SLIDER["step"]) -> dict:
    """The whole crank slider with the flexible coupler of crank_slider_flexible
    (COUPLER's beam: length, density, section, E, elements) as one
    :class:`~dsim.fmus.flexible_link.mechanism.FlexibleMechanism`; rows as
    :func:`monolithic` (``omega`` is the coupler's reference-frame rate, the scene's
    ``coupler.omega``), plus ``newton_iterations`` per step."""
    from dsim.fmus.flexible_link.mechanism import crank_slider_flexible

    beam = {key: COUPLER[key] for key in ("density", "area", "young", "second_moment",
                                           "elements")}
    whole = crank_slider_flexible(coupler=beam, baumgarte_damping=CRANK_SLIDER["xi"],
                                  baumgarte_frequency=CRANK_SLIDER["omega"])
    whole.initialize(0.0)
    link = whole.links["coupler"]
    slider_body = whole.rigid.body_names.index("slider")
    count = round(stop / step)
    force, omega, slider = np.zeros((count + 1, 2)), np.zeros(count + 1), np.zeros(count + 1)
    iterations = np.zeros(count + 1, dtype=int)
    slider[0] = whole.rigid.q[slider_body, 0]
    start = time.perf_counter()
    for n in range(count):
        whole.step(n * step, step)
        force[n + 1] = whole.forces[0]
        omega[n + 1] = link.omega
        slider[n + 1] = whole.rigid.q[slider_body, 0]
        iterations[n + 1] = whole.newton_iterations
    return {"times": np.arange(count + 1) * step, "force": force, "omega": omega,
            "slider": slider, "newton_iterations": iterations,
            "seconds": time.perf_counter() - start}


def compare(csv_path, reference: dict | None = None, flexible: bool = False) -> dict:
    """Glued (CSV) minus monolithic: largest differences of the force at A (vector,
    N), the coupler's angular velocity (rad/s) and the slider position (m), each
    also relative to the reference's peak; the t = 0 row is skipped (the master
    writes zero forces there, the mechanism starts at rest so they are zero).
    Without ``reference`` the monolithic model is run here, with the flexible
    coupler if ``flexible``."""
    from dsim.master.recording.results import read_csv

    header, data = read_csv(csv_path)
    times = data[:, 0]
    column = {name: data[:, header.index(name)] for name in header}
    if reference is None:
        reference = monolithic(stop=times[-1], step=times[1] - times[0], flexible=flexible)
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
    slider_peak = np.max(np.abs(result["reference_slider"]))
    result.update(force_error=float(force_error), force_peak=float(force_peak),
                  force_relative=float(force_error / force_peak),
                  omega_error=float(omega_error),
                  omega_relative=float(omega_error / np.max(np.abs(result["reference_omega"]))),
                  slider_error=float(slider_error),
                  slider_relative=float(slider_error / slider_peak))
    return result


def main(flexible: bool = False, plot: bool = False, stop: float | None = None,
         out_dir=ROOT / "results") -> dict:
    """Run crank_slider_rigid (or _flexible) through dsim and compare it with its
    monolithic reference; the flexible scene also with the rigid monolithic model
    (``result["rigid"]``, informational: the coupler's flexibility)."""
    from dsim.master.api import simulate

    name = "crank_slider_flexible" if flexible else "crank_slider_rigid"
    csv_path = Path(out_dir) / f"{name}.csv"
    statistics = simulate(ROOT / "build" / "ssp" / f"{name}.ssp", out=csv_path, stop=stop)
    result = compare(csv_path, flexible=flexible)
    result["statistics"] = statistics.statistics
    if flexible:
        result["rigid"] = compare(csv_path, flexible=False)
    if plot:
        plot_comparison(result, Path(out_dir) / f"{name}_vs_monolithic.png", name)
    return result


def plot_comparison(result: dict, png: Path, title: str) -> None:
    """Force magnitude at A, coupler angular velocity, slider position: glued over
    monolithic."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dsim.master.recording.results import save_figure

    figure, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 8))
    t = result["times"]
    for axis, key, label in zip(axes, ("force", "omega", "slider"),
                                ("|F_A| (N)", "coupler omega (rad/s)", "slider x (m)")):
        axis.plot(t, result[f"reference_{key}"], "k-", lw=2.5, label="monolithic (one model)")
        axis.plot(t, result[f"glued_{key}"], "C1--", label="glued (dsim, 3 FMUs)")
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
    axes[0].legend()
    axes[0].set_title(title)
    axes[-1].set_xlabel("time (s)")
    save_figure(figure, png)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--flexible", action="store_true", help="the flexible coupler scene")
    parser.add_argument("--stop", type=float, help="stop time, s (default: the scene's 5 s)")
    args = parser.parse_args()
    result = main(args.flexible, plot=True, stop=args.stop)
    print(f"glued vs monolithic: |F_A| difference {result['force_error']:.3e} N = "
          f"{result['force_relative']:.2e} of the peak {result['force_peak']:.4g} N; coupler "
          f"omega {result['omega_error']:.3e} rad/s = {result['omega_relative']:.2e} of its "
          f"peak; slider {result['slider_error']:.3e} m = {result['slider_relative']:.2e} of "
          f"its peak")
    if "rigid" in result:
        r = result["rigid"]
        print(f"(informational) glued flexible vs RIGID monolithic: |F_A| "
              f"{r['force_relative']:.2e} of the peak, coupler omega "
              f"{r['omega_relative']:.2e}, slider {r['slider_relative']:.2e} of the peaks "
              f"(the coupler's flexibility)")
