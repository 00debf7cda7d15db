"""Cost and accuracy of the linkage scenes, and the interface drift of the
crank slider glued on acceleration only versus the penalized measure.

Each scene runs from its .ssp archive through dsim (real FMUs); its monolithic
reference runs right after in the same process, so the wall-time ratio compares
runs made under the same load.  Writes docs/linkage_benchmark.md and PNGs of
the penalized-versus-acceleration interface errors into docs/.

    python -m benchmarks.linkage_benchmark [--stop 5] [--out docs/linkage_benchmark.md]
"""
from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

import numpy as np

from benchmarks import machine
from examples import crank_slider, four_bar
from dsim.master.api import simulate
from dsim.master.recording.results import read_csv

ROOT = Path(__file__).resolve().parent.parent
#: scene -> (reference description, function returning (reference, seconds))
CHECK_TIMES = (0.1, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0)


def _reference(scene: str, stop: float):
    if scene.startswith("crank_slider"):
        reference = crank_slider.monolithic(stop=stop, flexible="flexible" in scene)
        return reference, reference["seconds"]
    joints = scene.rsplit("_", 1)[1]
    reference = four_bar.monolithic(joints, stop=stop)
    return reference, reference["seconds"]


def measure(scene: str, out_dir: Path, stop: float | None) -> dict:
    """One glued run and its reference: the table's row."""
    csv_path = out_dir / f"{scene}.csv"
    run = simulate(ROOT / "build" / "ssp" / f"{scene}.ssp", out=csv_path, stop=stop)
    statistics = run.statistics
    failure = run.message if run.status == "failed" else None
    reached = statistics["steps"] * statistics["master"]["step"]
    mono, mono_seconds = _reference(scene, max(reached, statistics["master"]["step"]))
    if scene.startswith("crank_slider"):
        flexible = "flexible" in scene
        accuracy = crank_slider.compare(csv_path, mono, flexible=flexible)
        if flexible:
            # informational: the coupler's flexibility, not a gluing error
            rigid = crank_slider.compare(csv_path, flexible=False)
            reference = (f"flexible monolithic (one Newton, mechanism.py); rigid monolithic "
                         f"{rigid['force_relative']:.2e} away")
        else:
            reference = "rigid monolithic (one Linkage)"
    else:
        joints = scene.rsplit("_", 1)[1]
        accuracy = four_bar.compare(csv_path, joints)
        reference = {"fixed": "monolithic, A and B index-3 rows, the parts' generalized-alpha",
                     "penalized": "monolithic, fixed joints (Baumgarte rows)"}.get(
                         joints, f"monolithic, {joints} joints")
    components = statistics["components"]
    return {"scene": scene, "steps": statistics["steps"], "planned": statistics["planned_steps"],
            "wall": statistics["wall_seconds"], "mono": mono_seconds,
            "iterations": statistics["iterations"]["mean_per_step"],
            "max_iterations": statistics["iterations"]["max_per_step"],
            "refreshes": statistics["lambda_refreshes"],
            "do_steps": statistics["do_steps_per_step"] / len(components),
            "inside": statistics["seconds_in_fmus"], "reference": reference,
            "force_relative": accuracy["force_relative"], "force_peak": accuracy["force_peak"],
            "omega_error": accuracy["omega_error"], "failure": failure}


def table(rows: list[dict]) -> str:
    lines = ["| scene | steps | wall (s) | monolithic (s) | glued / monolithic | iterations per "
             "step (max) | Lambda refreshes | doSteps per FMU per step | s in FMUs | "
             "compared with | max norm dF_A / peak | max d omega (rad/s) | result |",
             "|" + "---|" * 13]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['steps']} / {r['planned']} | {r['wall']:.1f} | "
            f"{r['mono']:.2f} | {r['wall'] / r['mono']:.0f}x | {r['iterations']:.2f} "
            f"({r['max_iterations']}) | {r['refreshes']} | {r['do_steps']:.2f} | "
            f"{r['inside']:.1f} | {r['reference']} | {r['force_relative']:.2e} "
            f"(peak {r['force_peak']:.4g} N) | {r['omega_error']:.2e} | "
            f"{r['failure'] or 'ok'} |")
    return "\n".join(lines)


def interface_errors(csv_path) -> dict:
    """|u_b - u_a|, |v_b - v_a|, |a_b - a_a| at joint A (crank.A vs coupler.A) over time."""
    header, data = read_csv(csv_path)
    column = lambda name: data[:, header.index(name)]  # noqa: E731
    result = {"times": data[:, 0]}
    for kind in ("u", "v", "a"):
        result[kind] = np.hypot(column(f"coupler.A.{kind}_x") - column(f"crank.A.{kind}_x"),
                                column(f"coupler.A.{kind}_y") - column(f"crank.A.{kind}_y"))
    return result


def drift(out_dir: Path, stop: float | None, docs: Path) -> str:
    """Run both crank_slider_penalized variants; table of interface errors at A and
    PNG figures (the seed's Figs. 5.16-5.17)."""
    errors, rows = {}, []
    for scene, label in (("crank_slider_penalized_acceleration", "acceleration only"),
                         ("crank_slider_penalized", "penalized (xi 1, omega 1000)")):
        csv_path = out_dir / f"{scene}.csv"
        statistics = simulate(ROOT / "build" / "ssp" / f"{scene}.ssp", out=csv_path,
                              stop=stop).statistics
        errors[label] = interface_errors(csv_path)
        rows.append((label, statistics))
    lines = ["| measure | quantity at A | " + " | ".join(
        f"t = {t:g} s" for t in CHECK_TIMES) + " | max over the run | iterations per step |",
        "|" + "---|" * (len(CHECK_TIMES) + 4)]
    for label, statistics in rows:
        e = errors[label]
        for kind, unit in (("u", "m"), ("a", "m/s^2")):
            cells = []
            for t in CHECK_TIMES:
                i = np.searchsorted(e["times"], t - 1e-9)
                cells.append(f"{e[kind][i]:.2e}" if i < len(e["times"]) else "")
            lines.append(f"| {label} | norm of {kind}_b - {kind}_a ({unit}) | " + " | ".join(cells)
                         + f" | {np.max(e[kind][1:]):.2e} | "
                         f"{statistics['iterations']['mean_per_step']:.2f} |")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dsim.master.recording.results import save_figure

    for kind, name, unit in (("u", "displacement", "m"), ("a", "acceleration", "m/s^2")):
        figure, axis = plt.subplots(figsize=(8, 4))
        for label, e in errors.items():
            axis.semilogy(e["times"][1:], e[kind][1:] + 1e-20, label=label)
        axis.set_xlabel("time (s)")
        axis.set_ylabel(f"|{kind}_coupler.A - {kind}_crank.A| ({unit})")
        axis.set_title(f"crank_slider_penalized: interface {name} error at joint A")
        axis.grid(True, alpha=0.3)
        axis.legend()
        save_figure(figure, docs / f"crank_slider_penalized_{name}_error.png")
    return "\n".join(lines)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "linkage_benchmark.md"))
    parser.add_argument("--stop", type=float, help="stop time of every scene, s (default: each scene's own)")
    args = parser.parse_args(argv)
    out_dir = ROOT / "results" / "linkage_benchmark"
    docs = Path(args.out).parent
    rows = [measure("crank_slider_rigid", out_dir, args.stop),
            measure("crank_slider_flexible", out_dir, args.stop),
            measure("four_bar_singular_flexible", out_dir, args.stop),
            measure("four_bar_singular_fixed", out_dir, args.stop)]
    drift_table = drift(out_dir, args.stop, docs)
    text = "\n".join([
        "# Benchmarks: linkage scenes",
        "",
        f"Written by `python -m benchmarks.linkage_benchmark` on {time.strftime('%Y-%m-%d')} "
        f"({machine()}, Python {platform.python_version()}, one process, in-process "
        "backend). Each row is one glued run from the scene's .ssp archive through real "
        "pythonfmu FMUs; its monolithic reference (the same rule and step: one Linkage for the "
        "rigid mechanisms, one FlexibleMechanism, fmus/flexible_link/mechanism.py, for the "
        "flexible coupler) runs right after it in the same process. Scene settings as shipped (four bar at its "
        "default tolerance 1e-8 m), run to "
        + (f"t = {args.stop:g} s" if args.stop else "each scene's stop time") + ". The force error is the largest |F_A glued - F_A "
        "monolithic| over the run divided by the reference's peak |F_A|.",
        "",
        table(rows),
        "",
        "## crank_slider_penalized: acceleration-only versus penalized gluing",
        "",
        "The flexible crank slider glued at A and B on the acceleration measure alone, and on "
        "the penalized measure e_a + 2 xi omega e_v + omega^2 e_d (eq. 5.28). Interface errors "
        "at joint A (coupler.A against crank.A, vector norms):",
        "",
        drift_table,
        "",
        "![displacement error](crank_slider_penalized_displacement_error.png)",
        "![acceleration error](crank_slider_penalized_acceleration_error.png)",
        "",
    ])
    Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
