"""The seed's Table 5.1 through dsim, and what passes the four bar's singular points
with fixed joints on the displacement measure.

Part 1, Table 5.1: Lambda refreshes and total Newton iterations of the four bar glued
with fixed joints (displacement measure, and penalized), and with flexible joints, at
interface tolerances 1e-7 .. 1e-10 m (H = 0.01 s), under each refresh policy: the
seed's (re-measure Lambda after 10 iterations of a step), dsim's default adaptive one
(also once per step when Newton has slowed to a rate that predicts more iterations
than a refresh costs) and ``step`` (at the first iteration of every step).

Part 2, the means: the fixed scene's generalized-alpha parts, its refresh policy, its
convergence test and the master's step cuts, switched on one after the other, and the
parts' spectral radius rho_inf swept with the scene's settings.

Every case runs the shipped scene archive with :func:`dsim.simulate` and overrides,
as ``dsim run build/ssp/four_bar_singular_<joints>.ssp --tol <tol> --refresh <rule>``
would (the spectral radius through the loaded scene's component parameters, as a
parameter set would).  A run that fails (status ``failed``, exit code 1 on the command
line) is reported as failed at its step and time, with the counts up to the failure.
Each run's force error is against its own twin: the monolithic four bar that solves
the same discrete equations (build_fmus/twins/four_bar.py), with the same spectral
radius.

    python -m benchmarks.four_bar_table [--out docs/four_bar_table.md] [--stop 2]
"""
from __future__ import annotations

import argparse
import platform
import time
from dataclasses import replace
from functools import lru_cache
from pathlib import Path

from benchmarks import machine
from dsim.build_fmus.linkage_scenes import FOUR_BAR
from dsim.build_fmus.twins import four_bar_twin
from dsim.master.api import simulate
from dsim.master.planning.load import load_scene
from dsim.master.sweeps.sweep import error_against

ROOT = Path(__file__).resolve().parent.parent
#: The seed's Table 5.1 (refreshes, total iterations; None: failed at a singular point).
SEED = {("fixed", 1e-7): (None, None), ("fixed", 1e-8): (16, 4935),
        ("fixed", 1e-9): (18, 5217), ("fixed", 1e-10): (None, None),
        ("flexible", 1e-7): (0, 2616), ("flexible", 1e-8): (0, 3016),
        ("flexible", 1e-9): (0, 3457), ("flexible", 1e-10): (0, 3943)}
#: the scenes: fixed and flexible joints on the displacement measure (Table 5.1's
#: setting), and fixed joints on the penalized measure
JOINTS = ("fixed", "penalized", "flexible")
RULES = ("iterations", "adaptive", "step")
#: Part 2: the fixed scene's means one after the other (label, spectral radius,
#: settings); the last is the scene as shipped
MEANS = (
    ("trapezoidal parts, adaptive refresh, residual test (the scene until now)", 1.0,
     dict(refresh="adaptive", convergence="residual")),
    ("trapezoidal parts, refresh every step, forces test", 1.0, {}),
    ("generalized-alpha parts, adaptive refresh, residual test", None,
     dict(refresh="adaptive", convergence="residual")),
    ("generalized-alpha parts, refresh every step, residual test", None,
     dict(convergence="residual")),
    ("generalized-alpha parts, refresh every step, forces test, no step cuts", None,
     dict(step_cuts=0)),
    ("generalized-alpha parts, refresh every step, forces test (the scene)", None, {}),
)
#: Part 2: spectral radii swept with the scene's settings
RADII = (0.0, 0.3, 0.5, 0.8, 0.9)


@lru_cache(maxsize=None)
def _twin(joints: str, spectral_radius: float | None) -> dict:
    return four_bar_twin(joints, 1, spectral_radius)


def _scene(joints: str, spectral_radius: float | None):
    """The shipped scene, its parts' spectral radius replaced when one is given."""
    path = ROOT / "build" / "ssp" / f"four_bar_singular_{joints}.ssp"
    if spectral_radius is None:
        return path
    scene = load_scene(path)
    value = ("Real", float(spectral_radius))
    parts = tuple(replace(c, parameters={**c.parameters, "spectral_radius": value})
                  for c in scene.components)
    return replace(scene, components=parts)


def measure(joints: str, tolerance: float, out_dir: Path, stop: float | None = None,
            spectral_radius: float | None = None, label: str = "", **settings) -> dict:
    """One case: refreshes, iterations, steps done, force error against its twin, and
    the failure if any."""
    rule = settings.get("refresh", "scene")
    case = "".join(c if c.isalnum() else "_" for c in label)[:40]
    csv_path = out_dir / f"four_bar_{joints}_{tolerance:g}_{rule}_{case}.csv"
    run = simulate(_scene(joints, spectral_radius), out=csv_path, tolerance=tolerance,
                   stop=stop, **settings)
    stats = run.statistics
    # the joint force at A against the twin of the same discrete equations at the same
    # step, relative to its peak (over the converged steps of a failed run)
    radius = spectral_radius if joints == "fixed" else None
    error = error_against(run.signals, _twin(joints, radius), ["A.f_x", "A.f_y"])
    failure = run.error if run.status == "failed" else None
    row = {"joints": joints, "tolerance": tolerance, "refresh": stats["master"]["refresh"],
           "convergence": stats["master"].get("convergence", "residual"), "label": label,
           "do_steps": stats["do_steps_per_step"] / 3, "steps": stats["steps"],
           "planned": stats["planned_steps"], "refreshes": stats["lambda_refreshes"],
           "iterations": stats["iterations"]["total"],
           "mean": stats["iterations"]["mean_per_step"],
           "max": stats["iterations"]["max_per_step"], "wall": stats["wall_seconds"],
           "error": error, "cuts": stats["step_cuts"], "roundoff": stats["roundoff_steps"],
           "failure": None if failure is None else str(failure),
           "failed_step": None if failure is None else failure.step,
           "failed_time": None if failure is None else failure.time}
    print(f"{label or joints} {rule} {tolerance:g}: {row['failure'] or 'passed'}, "
          f"{row['mean']:.2f} iterations per step, error {error:.2e}", flush=True)
    return row


def _cell(row: dict, key: str) -> str:
    if row["failure"]:
        return (f"failed at step {row['failed_step']} (t = {row['failed_time']:.2f} s); "
                f"{row[key]} before")
    return str(row[key])


def table(rows: list[dict]) -> str:
    """Markdown: dsim's counts next to the seed's."""
    by = {(r["joints"], r["tolerance"]): r for r in rows}
    names = {"fixed": "fixed", "penalized": "fixed penalized", "flexible": "flexible"}
    lines = ["| tolerance (m) | " + " | ".join(f"{what}, {names[j]}" for what in
                                             ("refreshes", "iterations") for j in JOINTS)
             + " | seed refreshes fixed / flexible | seed iterations fixed / flexible |",
             "|" + "---|" * (3 + 2 * len(JOINTS))]
    show = lambda v: "-" if v is None else str(v)  # noqa: E731
    for tolerance in FOUR_BAR["tolerances"]:
        seed_fixed, seed_flexible = SEED[("fixed", tolerance)], SEED[("flexible", tolerance)]
        cells = [_cell(by[(j, tolerance)], what) for what in ("refreshes", "iterations")
                 for j in JOINTS]
        lines.append(f"| {tolerance:g} | " + " | ".join(cells) + " | "
                     f"{show(seed_fixed[0])} / {show(seed_flexible[0])} | "
                     f"{show(seed_fixed[1])} / {show(seed_flexible[1])} |")
    return "\n".join(lines)


def _outcome(row: dict) -> str:
    if row["failure"]:
        return f"failed at step {row['failed_step']} (t = {row['failed_time']:.2f} s)"
    return "passed"


def against_flexible(rows: list[dict]) -> str:
    """Markdown: fixed joints on the displacement measure beside the flexible ones, under
    the same refresh policy and against the flexible scene as shipped (adaptive)."""
    by = {(r["refresh"], r["joints"], r["tolerance"]): r for r in rows}
    lines = ["| refresh policy | tolerance (m) | fixed: result | fixed: iterations per step "
             "| fixed: force error / peak | flexible, same policy: iterations per step / "
             "force error | flexible as shipped (adaptive): iterations per step / force error "
             "| fixed within both? |", "|" + "---|" * 8]
    for rule in RULES:
        for tolerance in FOUR_BAR["tolerances"]:
            fixed, same = by[(rule, "fixed", tolerance)], by[(rule, "flexible", tolerance)]
            shipped = by[("adaptive", "flexible", tolerance)]
            within = (not fixed["failure"] and all(
                fixed["mean"] <= other["mean"] and fixed["error"] <= other["error"]
                for other in (same, shipped)))
            lines.append(
                f"| {rule} | {tolerance:g} | {_outcome(fixed)} | {fixed['mean']:.2f} | "
                f"{fixed['error']:.2e} | {same['mean']:.2f} / {same['error']:.2e} | "
                f"{shipped['mean']:.2f} / {shipped['error']:.2e} | "
                f"{'yes' if within else 'no'} |")
    return "\n".join(lines)


def means_table(rows: list[dict]) -> str:
    """Markdown: one row per combination of means, one column per tolerance."""
    tolerances = FOUR_BAR["tolerances"]
    lines = ["| means (fixed joints, displacement measure) | "
             + " | ".join(f"{t:g} m" for t in tolerances) + " |",
             "|" + "---|" * (1 + len(tolerances))]
    labels = list(dict.fromkeys(r["label"] for r in rows))
    by = {(r["label"], r["tolerance"]): r for r in rows}
    for label in labels:
        cells = []
        for tolerance in tolerances:
            r = by[(label, tolerance)]
            text = (_outcome(r) if r["failure"] else
                    f"{r['mean']:.2f} it/step, {r['do_steps']:.2f} doSteps/FMU/step")
            cells.append(f"{text}; error {r['error']:.1e}"
                         + (f"; {r['cuts']} cut" if r["cuts"] else ""))
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def details(rows: list[dict]) -> str:
    lines = ["| refresh rule | joints | tolerance | steps done / planned | iterations per step "
             "(max) | doSteps per FMU per step | steps cut | steps ended at round-off | "
             "force at A vs twin / peak | wall (s) | result |", "|" + "---|" * 11]
    for r in rows:
        lines.append(f"| {r['refresh']} | {r['joints']} | {r['tolerance']:g} | "
                     f"{r['steps']} / {r['planned']} | {r['mean']:.2f} ({r['max']}) | "
                     f"{r['do_steps']:.2f} | {r['cuts']} | {r['roundoff']} | {r['error']:.2e} | "
                     f"{r['wall']:.1f} | {r['failure'] or 'passed'} |")
    return "\n".join(lines)


INTRODUCTION = (
    "Scenes `four_bar_singular_fixed` and `four_bar_singular_flexible` (SCENES.md): crank, "
    "coupler and rocker as three Linkage2D FMUs glued at A and B (dofs x y, displacement "
    "measure); `four_bar_singular_penalized`: the fixed joints on the penalized measure "
    "(xi = 1, omega = 1000 rad/s, the Linkage parts' own Baumgarte row); H = {step} s, 0 to "
    "{stop:g} s (the crank passes the collinear positions at t = 0.375, 0.875, 1.375, "
    "1.875 s), predictor linear, at most {max_iterations} iterations per step, at most 4 "
    "step cuts. Flexible joints: k = 1e6 N/m, c = 2 0.707 1e3 N.s/m. The fixed scene's "
    "parts integrate with generalized-alpha (spectral radius rho_inf = {radius}), its "
    "master re-measures the interface flexibility at every step (`refresh=\"step\"`) and "
    "ends a step when the joint forces have converged too (`convergence=\"forces\"`); the "
    "other two scenes use the trapezoidal rule and dsim's defaults (adaptive refresh, "
    "residual test). The refresh policy is overridden in each section of part 1. The "
    "seed's counts (Matlab ode45/ode15s parts, its own run length) are shown for "
    "reference; only the pattern compares, not the numbers. The error column compares "
    "the joint force at A with the run's twin at the same step, relative to its peak "
    "(build_fmus/twins/four_bar.py): the monolithic four bar that solves the same discrete "
    "equations (fixed scene: revolutes A and B as position-level rows, generalized-alpha "
    "with the run's rho_inf; penalized: Baumgarte rows, trapezoidal; flexible: bushings, "
    "trapezoidal). Wall times are from a machine shared with other work.")


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "four_bar_table.md"))
    parser.add_argument("--stop", type=float, help=f"stop time, s (default {FOUR_BAR['stop']})")
    args = parser.parse_args(argv)
    out_dir = ROOT / "results" / "four_bar_table"
    tolerances = FOUR_BAR["tolerances"]
    rows = {rule: [measure(joints, tolerance, out_dir, args.stop, refresh=rule)
                   for joints in JOINTS for tolerance in tolerances] for rule in RULES}
    means = [measure("fixed", tolerance, out_dir, args.stop, radius, label, **settings)
             for label, radius, settings in MEANS for tolerance in tolerances]
    radii = [measure("fixed", tolerance, out_dir, args.stop, radius,
                     f"rho_inf = {radius:g}" + (" (the scene)" if radius ==
                                                 FOUR_BAR["spectral_radius"] else ""))
             for radius in RADII for tolerance in tolerances]
    stop = args.stop or FOUR_BAR["stop"]
    text = "\n".join([
        "# Four bar through its singular configuration: Table 5.1 by dsim",
        "",
        f"Written by `python -m benchmarks.four_bar_table` on {time.strftime('%Y-%m-%d')} "
        f"(Python {platform.python_version()}, {machine()}). "
        + INTRODUCTION.format(step=FOUR_BAR["step"], stop=stop,
                              max_iterations=FOUR_BAR["max_iterations"],
                              radius=FOUR_BAR["spectral_radius"]),
        "",
        "What changed (issue 19): until then the fixed scene's parts used the trapezoidal rule "
        "and its master dsim's default refresh and test, and the run failed at step 38 at every "
        "tolerance "
        "(part 2, first row); it now passes every singular point at every tolerance, closer "
        "to its twin than the flexible run is to its own. The penalized and flexible scenes "
        "are unchanged.",
        "",
        "## Part 1: Table 5.1",
        "",
        "### The seed's refresh rule (`refresh=\"iterations\"`, refreshAfter = 10)",
        "",
        table(rows["iterations"]),
        "",
        "### dsim's default (`refresh=\"adaptive\"`): also refresh, once per step, when "
        "Newton has slowed to a linear rate that predicts more iterations than a refresh "
        "costs",
        "",
        table(rows["adaptive"]),
        "",
        "### The fixed scene's (`refresh=\"step\"`): refresh at the first iteration of every "
        "step",
        "",
        table(rows["step"]),
        "",
        "### Fixed joints on the displacement measure against the flexible joints",
        "",
        "Iterations per step and force error against the twin, beside the flexible scene "
        "under the same refresh policy and as shipped.",
        "",
        against_flexible(rows["iterations"] + rows["adaptive"] + rows["step"]),
        "",
        "## Part 2: what each means contributes",
        "",
        "The fixed scene with its means switched on one after the other (trapezoidal: the "
        "parameter set `trapezoidal`, rho_inf = 1; its twin is the index-3 four bar under "
        "the trapezoidal rule). Each cell: the result, iterations and doSteps per FMU per "
        "step, and the force error against the twin with the same rule.",
        "",
        means_table(means),
        "",
        "The parts' spectral radius with the scene's settings (refresh every step, forces "
        "test): each run against the twin with the same rho_inf.",
        "",
        means_table(radii),
        "",
        "## Every run of part 1",
        "",
        details(rows["iterations"] + rows["adaptive"] + rows["step"]),
        "",
    ])
    Path(args.out).write_text(text)
    print(text)
    return {"rules": rows, "means": means, "radii": radii}


if __name__ == "__main__":
    main()
