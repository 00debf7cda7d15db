"""The seed's Table 5.1 through dsim: Lambda refreshes and total Newton
iterations of the four bar glued with fixed and with flexible joints, at
interface tolerances 1e-7 .. 1e-10 m (H = 0.01 s), once with the seed's refresh
rule (re-measure Lambda after 10 iterations of a step) and once with dsim's
default adaptive rule (also, once per step, when Newton has slowed to a linear
rate that predicts more iterations than a refresh costs).

Every case runs the shipped scene archive with :func:`dsim.simulate` and a
tolerance override, as ``dsim run build/ssp/four_bar_singular_<joints>.ssp
--tol <tol>`` would.  A run that fails (status ``failed``,
exit code 1 on the command line) is reported as failed at its step and time,
with the counts up to the failure.

    python -m benchmarks.four_bar_table [--out docs/four_bar_table.md] [--stop 2]
"""
from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

from build_fmus.linkage_scenes import FOUR_BAR
from examples.twins import four_bar_twin
from master.api import simulate
from master.sweep import error_against

ROOT = Path(__file__).resolve().parent.parent
#: The seed's Table 5.1 (refreshes, total iterations; None: failed at a singular point).
SEED = {("fixed", 1e-7): (None, None), ("fixed", 1e-8): (16, 4935),
        ("fixed", 1e-9): (18, 5217), ("fixed", 1e-10): (None, None),
        ("flexible", 1e-7): (0, 2616), ("flexible", 1e-8): (0, 3016),
        ("flexible", 1e-9): (0, 3457), ("flexible", 1e-10): (0, 3943)}
#: the scenes: fixed and flexible joints on the displacement measure (Table 5.1's
#: setting), and fixed joints on the penalized measure
JOINTS = ("fixed", "penalized", "flexible")


def measure(joints: str, tolerance: float, out_dir: Path, stop: float | None = None,
            refresh: str = "iterations") -> dict:
    """One case: refreshes, iterations, steps done, and the failure if any."""
    csv_path = out_dir / f"four_bar_{joints}_{tolerance:g}_{refresh}.csv"
    scene = ROOT / "build" / "ssp" / f"four_bar_singular_{joints}.ssp"
    run = simulate(scene, out=csv_path, tolerance=tolerance, stop=stop, refresh=refresh)
    stats = run.statistics
    # the joint force at A against the monolithic four bar of the same joints at the
    # same step, relative to its peak (over the converged steps of a failed run)
    twin = four_bar_twin("flexible" if joints == "flexible" else "fixed", 1)
    error = error_against(run.signals, twin, ["A.f_x", "A.f_y"])
    failure = run.error if run.status == "failed" else None
    return {"joints": joints, "tolerance": tolerance, "refresh": refresh,
            "do_steps": stats["do_steps_per_step"] / 3, "steps": stats["steps"],
            "planned": stats["planned_steps"], "refreshes": stats["lambda_refreshes"],
            "iterations": stats["iterations"]["total"],
            "mean": stats["iterations"]["mean_per_step"],
            "max": stats["iterations"]["max_per_step"], "wall": stats["wall_seconds"],
            "error": error, "cuts": stats["step_cuts"], "roundoff": stats["roundoff_steps"],
            "failure": None if failure is None else str(failure),
            "failed_step": None if failure is None else failure.step,
            "failed_time": None if failure is None else failure.time}


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


def details(rows: list[dict]) -> str:
    lines = ["| refresh rule | joints | tolerance | steps done / planned | iterations per step "
             "(max) | doSteps per FMU per step | steps cut | steps ended at round-off | "
             "force at A vs monolithic / peak | wall (s) | result |", "|" + "---|" * 11]
    for r in rows:
        lines.append(f"| {r['refresh']} | {r['joints']} | {r['tolerance']:g} | "
                     f"{r['steps']} / {r['planned']} | {r['mean']:.2f} ({r['max']}) | "
                     f"{r['do_steps']:.2f} | {r['cuts']} | {r['roundoff']} | {r['error']:.2e} | "
                     f"{r['wall']:.1f} | "
                     f"{r['failure'] or 'passed'} |")
    return "\n".join(lines)


def main(argv=None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "four_bar_table.md"))
    parser.add_argument("--stop", type=float, help=f"stop time, s (default {FOUR_BAR['stop']})")
    args = parser.parse_args(argv)
    out_dir = ROOT / "results" / "four_bar_table"
    rows = {refresh: [measure(joints, tolerance, out_dir, args.stop, refresh)
                      for joints in JOINTS
                      for tolerance in FOUR_BAR["tolerances"]]
            for refresh in ("iterations", "adaptive")}
    stop = args.stop or FOUR_BAR["stop"]
    text = "\n".join([
        "# Four bar through its singular configuration: Table 5.1 by dsim",
        "",
        f"Written by `python -m benchmarks.four_bar_table` on {time.strftime('%Y-%m-%d')} "
        f"(Python {platform.python_version()}, {platform.machine()}). Scenes "
        "`four_bar_singular_fixed` and `four_bar_singular_flexible` (SCENES.md): crank, "
        "coupler and rocker as three Linkage2D FMUs glued at A and B (dofs x y, displacement "
        "measure); `four_bar_singular_penalized`: the fixed joints on the penalized measure "
        "(xi = 1, omega = 1000 rad/s, the Linkage parts' own Baumgarte row); "
        f"H = {FOUR_BAR['step']} s, 0 to {stop:g} s (the crank passes the collinear "
        "positions at t = 0.375, 0.875, 1.375, 1.875 s), predictor linear, at most "
        f"{FOUR_BAR['max_iterations']} iterations per step. Flexible joints: k = 1e6 N/m, "
        "c = 2 0.707 1e3 N.s/m. The seed's counts (Matlab ode45/ode15s parts, its own run "
        "length) are shown for reference; only the pattern compares, not the numbers. The "
        "error column compares the joint force at A with the monolithic four bar of the same "
        "joints at the same step (examples/twins.py).",
        "",
        "What changed on 2026-11-25: every Newton loop also ends when its residual is at its "
        "round-off floor (docs/reproducibility.md); the column 'steps ended at round-off' "
        "counts the interface Newton's such steps. The fixed joints on the penalized measure "
        "at 1e-10 m failed at step 11 (adaptive) and step 1 (iterations) before: their "
        "residual stalled at 1.1e-10 to 2.1e-10, above the tolerance but at the measure's "
        "round-off floor (omega^2 = 1e6 times port positions of metres: 64 ulps are about "
        "1e-7). Now those steps end on the round-off test (152 of 200) and the adaptive run "
        "passes every singular point, 1.6e-9 of the peak force from the monolithic four bar. "
        "The monolithic twin of the fixed four bar, which failed under some OpenBLAS kernels "
        "at a collinear pass, passes under every one (5 of its 200 steps end on the "
        "round-off test); the force errors of the penalized runs moved with it (at most "
        "4.4e-9 of the peak). The flexible joints and the fixed joints on the displacement "
        "measure are unchanged. Wall times are from a machine shared with other work.",
        "",
        "## The seed's refresh rule (`refresh=\"iterations\"`, refreshAfter = 10)",
        "",
        table(rows["iterations"]),
        "",
        "## dsim's default (`refresh=\"adaptive\"`): also refresh, once per step, when "
        "Newton has slowed to a linear rate that predicts more iterations than a refresh "
        "costs",
        "",
        table(rows["adaptive"]),
        "",
        "## Every run",
        "",
        details(rows["iterations"] + rows["adaptive"]),
        "",
    ])
    Path(args.out).write_text(text)
    print(text)
    return rows


if __name__ == "__main__":
    main()
