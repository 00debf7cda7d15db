"""The shipped scenes under ``--step auto``: how far each is from its monolithic
reference against the scene's own fixed step, what it costs, and how the step moves.

For each scene: the monolithic reference (the same model in one solver) at a tenth of the
scene's step, the glued run at the scene's fixed step, and the glued run with
``--step auto`` at the tolerance named here (output every ``interval`` s, so the steps
can grow up to it).  The difference is max |glued - reference| over the run's rows (the
reference interpolated there), per compared column, as a share of the column's peak in
the reference; the band a run must stay within is the fixed step's own difference (the
accuracy the scene ships with).  CPU seconds of this process, one run each; the steps'
sizes over time are plotted.

    python -m benchmarks.step_auto_scenes   # writes docs/step_auto_scenes.md and its plot
"""
from __future__ import annotations

import argparse
from datetime import date
from pathlib import Path

import numpy as np

from benchmarks import cpu_seconds, machine
import dsim

ROOT = Path(__file__).resolve().parent.parent


def _shipped(*names):
    """The scene's own monolithic twin (``resources/reference.csv``, computed at a tenth
    of its step when the scene was built: build_fmus/twins), its ``names`` up to the stop
    time: a function of (archive, stop)."""
    def reference(ssp, stop):
        from dsim.master.recording.results import read_columns

        twin = read_columns(dsim.prepare(ssp).scene.reference)
        kept = twin["time"] <= stop + 1e-12
        return twin["time"][kept], {name: twin[name][kept] for name in names}
    return reference


def _crank_slider(ssp, stop, flexible: bool = False):
    """The whole crank slider (rigid, or with the floating-frame coupler) at 0.1 ms, a
    tenth of the scene's step (it ships no twin: too slow to compute at every build)."""
    from examples.crank_slider import monolithic

    r = monolithic(stop, 1e-4, flexible=flexible)
    return r["times"], {"coupler.omega": r["omega"], "A.f_y": r["force"][:, 1]}


#: scene, span (s), the tolerances E (the first one's steps plotted), the output
#: interval (s), its monolithic reference (a function of the archive and the stop time:
#: times, column -> values) at a tenth of its step
SCENES = (("spring_mass_nonlinear", 10.0, (1e-5, 1e-6), 0.5, _shipped("right.x[2]")),
          ("frame_split", 0.1, (1e-9, 1e-7), 1e-3, _shipped("cross_front.load.u_x")),
          ("crank_slider_rigid", 2.0, (1e-5, 1e-4), 0.01, _crank_slider),
          ("crank_slider_flexible", 1.0, (1e-5,), 0.01,
           lambda ssp, stop: _crank_slider(ssp, stop, flexible=True)),
          ("four_bar_singular_flexible", 0.5, (1e-5,), 0.05,
           _shipped("rocker.omega", "A.f_x")))


def off(result, times, reference: dict) -> dict:
    """Per column: max |run - reference| over the run's rows, over the reference's peak."""
    return {name: float(np.max(np.abs(result[name] - np.interp(result["time"], times,
                                                                  values))))
            / float(np.max(np.abs(values))) for name, values in reference.items()}


def measure(only=None) -> list[dict]:
    """Every scene's reference, fixed-step and step-auto runs: a row per tolerance."""
    rows = []
    for name, stop, tolerances, interval, reference in SCENES:
        if only and name not in only:
            continue
        ssp = ROOT / "build" / "ssp" / f"{name}.ssp"
        times, columns = reference(ssp, stop)
        fixed_seconds, fixed = cpu_seconds(lambda: dsim.simulate(ssp, stop=stop,
                                                          handle_signals=False))
        if not fixed.ok:
            raise RuntimeError(f"{name}: {fixed.message}")
        for tolerance in tolerances:
            execution = dsim.Execution(dsim.prepare(ssp, stop=stop, step="auto",
                                                    error_tolerance=tolerance,
                                                    output_interval=interval))
            auto_seconds, auto = cpu_seconds(lambda: execution.run(handle_signals=False))
            if not auto.ok:
                raise RuntimeError(f"{name}: {auto.message}")
            row = {"scene": name, "stop": stop, "tolerance": tolerance,
                   "interval": interval, "plotted": tolerance == tolerances[0],
                   "fixed_step": fixed.statistics["master"]["step"],
                   "fixed": off(fixed, times, columns), "auto": off(auto, times, columns),
                   "fixed_seconds": fixed_seconds, "auto_seconds": auto_seconds,
                   "control": auto.statistics["step_control"],
                   "times": np.array(execution.controller.times),
                   "sizes": np.array(execution.controller.sizes)}
            rows.append(row)
            print(f"{name} E = {tolerance:g}: fixed {row['fixed']}, auto {row['auto']}, "
                  f"{fixed_seconds:.1f} s / {auto_seconds:.1f} s", flush=True)
    return rows


def plot(rows: list[dict], png: Path) -> None:
    """The accepted step over time, one panel per scene."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [row for row in rows if row["plotted"]]
    figure, panels = plt.subplots(len(rows), 1, figsize=(7.5, 2.4 * len(rows)))
    for axes, row in zip(np.atleast_1d(panels), rows):
        axes.step(row["times"], row["sizes"], where="post", label="step auto")
        axes.axhline(row["fixed_step"], color="grey", linestyle="--",
                     label="the scene's fixed step")
        axes.set_yscale("log")
        axes.set_ylabel("step (s)")
        axes.set_title(f"{row['scene']}, E = {row['tolerance']:g}, output every "
                       f"{row['interval']:g} s", fontsize=10)
        axes.grid(True, which="both", alpha=0.3)
        axes.legend(fontsize=8, loc="lower right")
    np.atleast_1d(panels)[-1].set_xlabel("time (s)")
    figure.tight_layout()
    figure.savefig(png, dpi=110)
    plt.close(figure)


def _where(row: dict) -> str:
    """Where the smallest and the largest steps were, read from the run."""
    times, sizes = row["times"], row["sizes"]
    small = times[sizes <= sizes.min() * (1 + 1e-9)]
    share = float(np.sum(sizes[sizes >= sizes.max() * (1 - 1e-9)])) / row["stop"]
    return (f"{row['scene']}: the smallest step, {sizes.min():.3g} s, from t = "
            f"{small.min():.4g} to {small.max():.4g} s; the largest, {sizes.max():.3g} s, "
            f"over {100 * share:.0f} % of the run.")


def page(rows: list[dict]) -> str:
    """docs/step_auto_scenes.md."""
    lines = [
        "# The shipped scenes under `--step auto` (`python -m benchmarks.step_auto_scenes`)",
        "",
        f"Measured {date.today().isoformat()} on {machine()}, by "
        "`benchmarks/step_auto_scenes.py` (its docstring says how). Each scene against its "
        "monolithic reference at a tenth of its step: the glued run at the scene's own "
        "fixed step (the band: the accuracy the scene ships with) and with `--step auto` at "
        "the tolerance E named here. Differences are max \\|glued - reference\\| over the "
        "run, as a share of the column's peak; CPU seconds of one run.",
        "",
        "![the accepted step over time](figures/step_auto_scenes.png)",
        "",
        "| scene | E | output every | column | fixed step: off | step auto: off | auto / fixed "
        "| steps (taken again), s | CPU fixed / auto |",
        "|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        control = row["control"]
        for k, column in enumerate(row["fixed"]):
            head = (f"{row['scene']} 0..{row['stop']:g} s | {row['tolerance']:g} | "
                    f"{row['interval']:g} s" if k == 0 else " | | ")
            tail = (f"{control['accepted_steps']} ({control['rejected_steps']}), "
                    f"{control['smallest_step']:.3g} .. {control['largest_step']:.3g} | "
                    f"{row['fixed_seconds']:.1f} / {row['auto_seconds']:.1f} s"
                    if k == 0 else " | ")
            fixed, auto = row["fixed"][column], row["auto"][column]
            ratio = auto / fixed
            shown = f"{ratio:.2f}" if ratio >= 0.01 else f"{ratio:.2g}"
            lines.append(f"| {head} | {column} | {fixed:.3g} | {auto:.3g} | {shown} | {tail} |")
    def named(these):
        return ", ".join(f"{r['scene']} at E = {r['tolerance']:g}" for r in these)

    within = [r for r in rows if all(r["auto"][c] <= r["fixed"][c] for c in r["auto"])]
    outside = [r for r in rows if r not in within]
    lines += ["", "What it shows, read from this run:", ""]
    if within:
        lines.append(f"- Within the band (no farther from the reference than the scene's "
                     f"fixed step, in every column): {named(within)}.")
    if outside:
        lines.append(f"- Outside it: {named(outside)}.")
    for row in rows:
        if row["plotted"]:
            ratio = row["auto_seconds"] / row["fixed_seconds"]
            lines.append(f"- {_where(row)} CPU {ratio:.2f} times the fixed step's.")
    lines += ["", "E weighs `E + E |x|`: its absolute part is in the quantity's own unit, so a "
              "scene whose interface moves by micrometres (frame_split's ports) needs an E "
              "below its motion: compare its two rows.", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "step_auto_scenes.md"))
    parser.add_argument("--scene", action="append", help="only this scene (again for more)")
    args = parser.parse_args(argv)
    rows = measure(args.scene)
    out = Path(args.out)
    plot(rows, out.parent / "figures" / "step_auto_scenes.png")
    out.write_text(page(rows))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
