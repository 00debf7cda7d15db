"""frame_split glued through dsim against the monolithic finite-element solve, and the
Craig-Bampton error table; writes docs/frame_benchmark.md.

``python -m benchmarks.frame_benchmark [--stop 0.2]`` (OMP_NUM_THREADS=1). Both solves
run in this process, one after the other, on the same machine: the ratio is what the
gluing costs over solving the frame as one mesh. A short glued run is profiled to say
where the time goes.
"""
from __future__ import annotations

import argparse
import cProfile
import io
import platform
import pstats
import tempfile
import time
from datetime import date
from pathlib import Path

import numpy as np

from benchmarks import machine
from dsim.build_fmus.frame_scenes import part_parameters
from dsim.fmus.elastic import craig_bampton_error, frame
from dsim.fmus.elastic.body_spec import build_body, spec_from_parameters

ROOT = Path(__file__).resolve().parent.parent
MODES = (5, 10, 20, 40, 60)
#: the ElasticBody FMU's resources (the parts' mesh files)
SCENE = ROOT / "ssp" / "frame_split"  # its mesh_file values are paths in it
CB_STEPS = 500


#: what issue 30 tried on the glued step, measured on 2026-11-27 (these 2-core machines,
#: shared: CPU seconds, least of several runs, A and B in turn); the ratio above is after it
LEVERS = (
    "Issue 30 (2.28 before it): the same scene run by the code before and after, in turn "
    "in separate processes, 9 runs of 0.2 s each, took 1.795 and 1.674 CPU seconds at "
    "least (-7%; glued / monolithic in CPU seconds 2.31 to 2.33 before, 2.13 to 2.17 "
    "after, three rounds), every result byte-identical (`dsim regress`, each CSV compared "
    "byte by byte with the code before). Kept, each switched off alone in one process "
    "(12 runs of 0.05 s in turn, CPU seconds at least; alone each is within 0 to 6% from "
    "run to run): the Newmark step's two sparse products by scipy's own kernel without "
    "its dispatch (+6 to 9% when off, in three runs; the monolithic solve gains it too); a batch of port positions "
    "read straight from the body's state instead of the binding's full vectors (the "
    "reads inside the FMU went from 72 to 37 us per macro step); one master call per FMU "
    "and trial (the master's Python 20 us per step less, 147 against 126 us on a busy "
    "machine); a batch found by comparing it with the last one (+4 to 5% when off); "
    "numpy's einsum kernel called without its Python wrapper (+3%); the repeat's start "
    "compared without np.array_equal's dispatch (+0 to 2%); the dense gluing solve by the "
    "LAPACK routine lu_solve calls, found once (2.4 against 6.2 us per solve, one per "
    "step: below the noise of a run). Not done: reusing FMU states "
    "(FMI 2.0 lets fmi2GetFMUstate overwrite a state passed in, but pythonfmu 0.7 always "
    "returns a new Python object and ignores the old one, which would leak; the free is "
    "a decref, about 1 us); one timer pair per fused trial instead of per call (a chain "
    "of five perf_counter readings per trial keeps the per-call table, a fraction of a "
    "microsecond each); the output row from the last trial's values (frame_split records "
    "the load point's probe, not the port positions the trials read: other variables; "
    "reading both in each trial's one fmi2GetReal, measured on 2026-11-27, 8 runs of "
    "0.2 s in turn in separate processes: 1.74 to 1.93 CPU seconds against 1.74 to 1.82 "
    "without, for the ElasticBody answers a batch of one kinematic kind straight from "
    "its state and a mixed one through its full vectors; chain_10000 gained 3 to 6% "
    "from it, docs/scaling.md); "
    "a shortcut for a converged step (there is one: Newton ends after the first trial "
    "when it is within the tolerance, which the predictor's never is here, and the "
    "corrected forces need their own trial); FMI calls that keep the GIL (ctypes.PyDLL: "
    "2.8 us per fmi2GetReal of 30 values either way, nothing to win with one thread); "
    "the garbage collector (3 to 6 passes per 1000 steps, 5 to 40 ms). Tried earlier and "
    "not kept: a body's saved state holding its arrays instead of copies (1%, within the "
    "noise, and ElasticBody.get_state would no longer return a state the caller may "
    "change)."
    " Nor the five parts stepped on two threads (each Newton trial's calls of the "
    "five FMUs handed to a pool of two threads in the in-process backend: scipy's "
    "SuperLU solve lets go of Python's lock, and two threads solving alone ran 1.7 "
    "times as fast): frame_split took 9.6 to 10.3 s against 5.8 to 6.8 s one after "
    "the other, the same bytes, on an AMD EPYC on 2026-11-27, whether ctypes let go "
    "of the lock around each FMI call or kept it: the Python around the solves needs "
    "the lock, and it changes hands at every FMI call and numpy operation.")


def glued_versus_monolithic(stop: float, repetitions: int = 3) -> dict:
    """Wall times, the error and the run statistics of frame_split over [0, stop].

    After one short warm-up of each (imports, first-use caches), the glued run, the
    monolithic solve and the floor (the five bare cores, each stepped twice per macro
    step with a state save and restore: what two doSteps cost without FMI or master)
    run in turn ``repetitions`` times; the least time of each is the one least
    disturbed by other work on a shared machine."""
    from examples.frame import compare
    from dsim.master.api import simulate

    scene = ROOT / "build" / "ssp" / "frame_split.ssp"
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "frame_split.csv"
        simulate(scene, stop=0.002, handle_signals=False)
        frame.monolithic_frame(stop_time=0.002)
        glued, monolithic, floor, cpu = [], [], [], []
        for _ in range(repetitions):
            start = time.process_time()
            statistics = simulate(scene, out=out, stop=stop, handle_signals=False).statistics
            middle = time.process_time()
            glued.append(statistics["wall_seconds"])
            reference = frame.monolithic_frame(stop_time=stop)
            cpu.append((middle - start) / (time.process_time() - middle))
            monolithic.append(reference.wall_time)
            floor.append(bare_cores_twice(stop))
        result = compare(out, reference)
    return {"statistics": statistics, "glued_seconds": min(glued),
            "monolithic_seconds": min(monolithic), "floor_seconds": min(floor),
            "ratios": [g / m for g, m in zip(glued, monolithic)], "cpu_ratios": cpu,
            "relative_error": result["relative_error"], "peak": result["peak"]}


def bare_cores_twice(stop: float) -> float:
    """Seconds to build the five parts' cores and step each twice per macro step (a
    state save and restore between, the repeat with other forces, as a Newton
    correction), no FMI and no master: the glued run's floor."""
    rng = np.random.default_rng(0)
    start = time.perf_counter()
    bodies = []
    for part in frame.COMPONENTS:  # as frame_split's FMUs build them
        bodies.append(build_body(spec_from_parameters(part_parameters(part)), SCENE))
        bodies[-1].initialize(0.0)
    for n in range(round(stop / frame.STEP_SIZE)):
        for body in bodies:
            saved = body.get_state()
            body.step(n * frame.STEP_SIZE, frame.STEP_SIZE)
            body.set_state(saved)
            body.set_interface_forces(1e-3 * rng.standard_normal(len(body.interface)))
            body.step(n * frame.STEP_SIZE, frame.STEP_SIZE)
    return time.perf_counter() - start


#: the FMU's Python methods behind the FMI calls of a glued step (pythonfmu calls them)
SLAVE_METHODS = {"do_step": "fmi2DoStep", "get_real": "fmi2GetReal", "set_real": "fmi2SetReal",
                 "_get_fmu_state": "fmi2GetFMUstate", "_set_fmu_state": "fmi2SetFMUstate"}
#: what the master's counters time per FMI call in the step loop
LOOP_FUNCTIONS = (*SLAVE_METHODS.values(), "fmi2FreeFMUstate")


def time_budget(stop: float = 0.1) -> dict:
    """Seconds per macro step of a glued run, split by where they go: the parts' full
    Newmark steps, the repeated steps (q1 + Z dF, the start compared), the FMU's Python
    around them (the binding, the slot layout, pythonfmu's Python callbacks), the crossing
    from the master's ctypes call into that Python and back (the master's timing of each
    FMI call less the time inside its Python), the master's own Python in the step loop,
    and the set-up once.  pythonfmu runs an FMU's Python in this process, so its methods
    can be timed from here: they are wrapped for this one run (a perf_counter pair per
    call, a fraction of a microsecond) and restored after."""
    import sys
    from dsim.master.api import simulate

    scene = ROOT / "build" / "ssp" / "frame_split.ssp"
    simulate(scene, stop=0.002, handle_signals=False)  # imports the FMU's modules
    # the FMU's own copies of its modules (from its resources folder, not dsim.fmus)
    slave = sys.modules["elastic_body_fmu"].ElasticBody
    newmark = sys.modules["fmus.elastic.newmark"].NewmarkAverageAcceleration
    repeat = sys.modules["fmus.elastic.retry"].RepeatedStep
    binding = sys.modules["fmus.fmi_binding"].CoreBinding
    seconds: dict[str, float] = {}
    wrapped = [(slave, name, name) for name in SLAVE_METHODS] + [
        (newmark, "step", "full steps"), (repeat, "step", "all steps"),
        (binding, "build", "build")]  # the bodies built at the first read: set-up
    originals = [(owner, name, owner.__dict__.get(name)) for owner, name, _ in wrapped]

    def timed(function, label):
        def call(*args, **keywords):
            start = time.perf_counter()
            try:
                return function(*args, **keywords)
            finally:
                seconds[label] = seconds.get(label, 0.0) + time.perf_counter() - start
        return call

    try:
        for owner, name, label in wrapped:
            setattr(owner, name, timed(getattr(owner, name), label))
        with tempfile.TemporaryDirectory() as folder:
            statistics = simulate(scene, out=Path(folder) / "budget.csv", stop=stop,
                                  handle_signals=False).statistics
    finally:
        for owner, name, original in originals:
            if original is None:
                delattr(owner, name)
            else:
                setattr(owner, name, original)
    # the monolithic solve of the same span right after, for a comparison made under the
    # same load; its set-up (the one mesh) left out: the same solve over two steps
    # subtracted
    short = 2 * frame.STEP_SIZE
    monolithic = (frame.monolithic_frame(stop_time=stop).wall_time
                  - frame.monolithic_frame(stop_time=short).wall_time)
    timed_by_master = sum(entry["seconds"] for component in statistics["components"].values()
                          for name, entry in component["functions"].items()
                          if name in LOOP_FUNCTIONS)
    inside = sum(seconds.get(name, 0.0) for name in SLAVE_METHODS) - seconds.get("build", 0.0)
    steps = statistics["steps"]
    budget = {"full Newmark steps of the parts (sparse solve and its vectors)":
              seconds["full steps"],
              "repeated steps (q1 + Z dF, the start compared)":
              seconds["all steps"] - seconds["full steps"],
              "the FMU's Python around them (binding, slot layout, state copies, reads)":
              inside - seconds["all steps"],
              "crossing: the master's ctypes call into the FMU's Python and back":
              timed_by_master - seconds.get("build", 0.0) - inside,
              "the master's Python in the step loop (Newton, rows)":
              statistics["phases"]["steps"] - (timed_by_master - seconds.get("build", 0.0))}
    return {"per_step_us": {k: 1e6 * v / steps for k, v in budget.items()},
            "setup": statistics["setup_seconds"], "steps": steps,
            "monolithic_us": 1e6 * monolithic / (steps - round(short / frame.STEP_SIZE)),
            "wall": statistics["wall_seconds"],
            "calls": {name: 1e6 * (seconds.get(name, 0.0)
                                   - (seconds.get("build", 0.0) if name == "get_real" else 0.0))
                      / steps for name in SLAVE_METHODS},
            "build": seconds.get("build", 0.0)}


def profile_glued(stop: float = 0.05, top: int = 16) -> tuple[str, dict]:
    """cProfile of a short glued run: the functions with most own time, and the
    profiled seconds in total, in the FMU's Python answering the FMI calls (the
    binding and its physics) and in the parts' sparse Newmark solves."""
    from dsim.master.api import simulate

    profiler = cProfile.Profile()
    with tempfile.TemporaryDirectory() as folder:
        simulate(ROOT / "build" / "ssp" / "frame_split.ssp", stop=0.002, handle_signals=False)
        profiler.enable()
        simulate(ROOT / "build" / "ssp" / "frame_split.ssp", out=Path(folder) / "p.csv",
                 stop=stop, handle_signals=False)
        profiler.disable()
    text = io.StringIO()
    stats = pstats.Stats(profiler, stream=text)
    stats.sort_stats("tottime").print_stats(top)
    shares = {"total": stats.total_tt, "fmi": 0.0, "solves": 0.0, "fmi_calls": 0}
    for (file, _, function), (_, calls, own, cumulative, _) in stats.stats.items():
        # what pythonfmu calls in the FMU's Python for the step loop's FMI calls
        if file.endswith("fmi_binding.py") and function in SLAVE_METHODS:
            shares["fmi"] += cumulative
            shares["fmi_calls"] += calls
        elif "SuperLU" in function and "solve" in function:
            shares["solves"] += own
    return text.getvalue(), shares


def solve_milliseconds(repeats: int = 300) -> tuple[float, float]:
    """Milliseconds of one sparse Newmark solve (K_eff^-1 rhs, factored once) of the
    five parts together and of the one mesh, measured bare: the finite-element work of
    a first trial step against the monolithic step's."""
    def each(integrator) -> float:
        integrator.factor(frame.STEP_SIZE)
        rhs = np.ones(integrator.stiffness.shape[0])
        integrator.solve(rhs)
        start = time.process_time()
        for _ in range(repeats):
            integrator.solve(rhs)
        return 1e3 * (time.process_time() - start) / repeats

    parts = sum(each(build_body(spec_from_parameters(part_parameters(part)), SCENE)
                     .integrator) for part in frame.COMPONENTS)
    return parts, each(frame.frame_body(frame.ELEMENT_SIZE, None).integrator)


def part_step_seconds(part: str, modes: int | None, steps: int = 300) -> float:
    """Seconds per Newmark step of one frame part alone (ports glued, forces zero)."""
    reduced = {"fidelity": "craig_bampton", "modes": modes} if modes else {}
    body = build_body(spec_from_parameters({**part_parameters(part), **reduced}), SCENE)
    body.initialize(0.0)
    start = time.perf_counter()
    for n in range(steps):
        body.step(n * frame.STEP_SIZE, frame.STEP_SIZE)
    return (time.perf_counter() - start) / steps


def craig_bampton_table() -> list[dict]:
    """Rail_left driven at its three port edges (y, 25 Hz), reduced vs full, 500 steps."""
    def build(modes):
        return frame.rail("left", modes=modes)

    size = len(build(None).interface)

    def forces(t):  # 100 N per port node in y, at the load's 25 Hz
        return np.tile([0.0, 100.0 * np.sin(50 * np.pi * t)], size // 2)

    rows = [{"modes": "full", "coordinates": build(None).stiffness.shape[0],
             "response": 0.0, "frequency": 0.0,
             "step_ms": 1e3 * part_step_seconds("rail_left", None)}]
    for modes in MODES:
        error = craig_bampton_error(build, modes, frame.STEP_SIZE, CB_STEPS, forces)
        rows.append({"modes": modes, "coordinates": build(modes).stiffness.shape[0],
                     "response": error.response, "frequency": error.frequency,
                     "step_ms": 1e3 * part_step_seconds("rail_left", modes)})
    return rows


def write_report(stop: float, path: Path = ROOT / "docs" / "frame_benchmark.md") -> str:
    run = glued_versus_monolithic(stop)
    stats = run["statistics"]
    glued, mono, floor = run["glued_seconds"], run["monolithic_seconds"], run["floor_seconds"]
    inside = stats["seconds_in_fmus"]
    functions: dict = {}
    for component in stats["components"].values():
        for name, entry in component["functions"].items():
            total = functions.setdefault(name, [0, 0.0])
            total[0] += entry["calls"]
            total[1] += entry["seconds"]
    core_ms = {p: 1e3 * part_step_seconds(p, None) for p in ("rail_left", "cross_front")}
    budget = time_budget()
    profile, shares = profile_glued()
    parts_ms, mesh_ms = solve_milliseconds()
    table = craig_bampton_table()
    ratios = ", ".join(f"{r:.2f}" for r in run["ratios"])
    cpu_ratios = ", ".join(f"{r:.2f}" for r in run["cpu_ratios"])
    calls_per_step = sum(calls for calls, _ in functions.values()) / stats["steps"]
    lines = [
        "# frame_split: glued versus monolithic, and Craig-Bampton", "",
        f"Written by `python -m benchmarks.frame_benchmark` on {date.today()} ({machine()}, "
        f"Python {platform.python_version()}, OMP_NUM_THREADS=1, one process, the in-process "
        "backend). Scene: build/ssp/frame_split.ssp, five ElasticBody FMUs "
        f"glued on six edges, H = 1e-4 s, 0 to {stop:g} s ({stats['steps']} steps). After a "
        "short warm-up of each, the glued run, the monolithic solve and the floor run in turn "
        f"{len(run['ratios'])} times; the table gives the least wall time of each (set-up "
        "included: instantiating and initialising the FMUs, building the one mesh).", "",
        "## Glued versus monolithic", "",
        "| quantity | value |", "|---|---|",
        f"| glued wall time (`dsim.simulate`, CSV written) | {glued:.2f} s |",
        f"| monolithic FE solve (one mesh, same Newmark rule and step) | {mono:.2f} s |",
        f"| ratio glued / monolithic | {glued / mono:.2f} (each repetition: {ratios}) |",
        f"| the same ratio in CPU seconds of this process (each repetition) | {cpu_ratios} |",
        f"| floor: the five bare cores, each stepped twice per step (a state save and "
        f"restore between, other forces the second time), no FMI and no master | {floor:.2f} s ({floor / mono:.2f} x monolithic) |",
        f"| load-point error, relative to the peak ({run['peak']:.3e} m) | "
        f"{run['relative_error']:.2e} |",
        f"| iterations per step (mean / max) | {stats['iterations']['mean_per_step']:.2f} / "
        f"{stats['iterations']['max_per_step']} |",
        f"| Lambda refreshes / factorizations | {stats['lambda_refreshes']} / "
        f"{stats['lambda_factorizations']} |",
        f"| doSteps per FMU per step | {stats['do_steps_per_step'] / 5:.2f} |",
        f"| set-up (instantiate, initialise) | {stats['setup_seconds']:.2f} s |",
        f"| FMI calls per macro step, all five FMUs | {calls_per_step:.1f} |",
        f"| one sparse Newmark solve, measured bare: the five parts together / the one "
        f"mesh | {parts_ms:.3f} ms / {mesh_ms:.3f} ms |",
        f"| time inside the FMUs | {inside:.2f} s ({100 * inside / stats['wall_seconds']:.0f}% "
        "of the wall time) |",
        "", "FMI calls of the last glued run, all five FMUs together:", "",
        "| function | calls | seconds | microseconds per call |", "|---|---|---|---|",
    ]
    for name, (calls, seconds) in sorted(functions.items(), key=lambda item: -item[1][1]):
        if seconds > 1e-3:
            lines.append(f"| {name} | {calls} | {seconds:.3f} | {1e6 * seconds / calls:.1f} |")
    lines += [
        "", "The bare core step (ElasticBody.step, no FMI) takes "
        f"{core_ms['rail_left']:.3f} ms for a rail and {core_ms['cross_front']:.3f} ms for a "
        "cross member.", "",
        "## Where the time goes", "",
        f"One glued run of {budget['steps']} steps, the FMU's Python methods timed from "
        "this process (pythonfmu runs an FMU's Python in the master's interpreter), "
        "microseconds per macro step, all five parts together (`time_budget`):", "",
        "| where | us per macro step | share |", "|---|---|---|",
    ]
    total_us = sum(budget["per_step_us"].values())
    for where, us in budget["per_step_us"].items():
        lines.append(f"| {where} | {us:.0f} | {100 * us / total_us:.0f}% |")
    mono_us = budget["monolithic_us"]
    work_us = sum(list(budget["per_step_us"].values())[:2])
    lines += [
        f"| all of the step loop | {total_us:.0f} | 100% |",
        f"| for comparison: one monolithic step (its set-up left out), the same span "
        f"right after | {mono_us:.0f} | |",
        "", "Inside the FMU's Python, per macro step: " + ", ".join(
            f"{name} {us:.0f} us" for name, us in budget["calls"].items()) + ". "
        f"Set-up besides: {budget['setup']:.2f} s ({1e6 * budget['setup'] / budget['steps']:.0f} "
        "us per step of this run), of which the five bodies' meshes, matrices and "
        f"factorizations {budget['build']:.2f} s.", "",
        "1. Two doSteps per part per macro step: the predicted force, then one Newton "
        "correction (the bodies are linear and Lambda exact, so the second trial converges; "
        "a first trial within the tolerance would end the step there, but the predictor's "
        "never is). Together the five parts have about as many coordinates as the one mesh, "
        "so the first trial's finite-element work is about one monolithic step. The second "
        "starts from the same state with other forces; a linear body answers it with its "
        "interface response, q2 = q1 + Z (F2 - F1) with Z = K_eff^-1 B^T built once per step "
        "size (fmus/elastic/retry.py): a dense product of coordinates x interface dofs "
        "instead of a sparse solve. With two full solves the floor was 1.98 x the "
        "monolithic solve.",
        "2. The FMU's Python around each solve, per trial: the restore (copies of q, v, a), "
        "the forces into the slot layout and the body, the positions read. A batch of one "
        "kind (the port positions a Newton iteration reads) is read straight from the "
        "body's state (`kinematic_reader`: the reference plus the picked coordinates), "
        "other batches through the binding's full vectors; the binding finds a batch by "
        "comparing it with the last one before hashing it.",
        "3. The crossing: about 46 FMI calls per macro step (per part: the forces, the step "
        "and the positions twice, a state restore, save and free; the output row), each "
        "pythonfmu's C into Python and back (it builds a Python list of the value "
        "references and of the values, and drains its log queue, every call).",
        "4. The master: one call per FMU and trial (`CoSimulation2Subsystem.trial_step`: restore, "
        "forces, step, positions, each still counted, timed and checked), the residual, "
        "the joint forces split per part and one solve with the factored gluing matrix per "
        "iteration (factored once for the whole run: every step has the same size to the "
        "last bit), and the CSV row.",
        "",
        "**Profile summary** (the profile below, a 0.05 s glued run under cProfile, which "
        f"inflates Python calls): {shares['total']:.2f} s in all, "
        f"{shares['fmi']:.2f} s ({100 * shares['fmi'] / shares['total']:.0f}%) in the FMUs' "
        f"Python answering {shares['fmi_calls']} FMI calls (the set-up's reads included), "
        f"of which {shares['solves']:.2f} s "
        f"({100 * shares['solves'] / shares['total']:.0f}% of all) are the parts' sparse "
        "Newmark solves.",
        "",
        "**Why not 1.6.** The parts' finite-element work alone (the first two rows above, "
        f"{work_us:.0f} us per step) is {work_us / mono_us:.2f} x a monolithic step; the "
        f"floor (the bare cores, twice per step) {floor / mono:.2f} x the monolithic solve. "
        f"Measured bare, one sparse solve of the five parts together costs {parts_ms:.3f} "
        f"ms and the one mesh's {mesh_ms:.3f} ms, but in a run each part's solve evicts the "
        "others' factors from the cache, and five small bodies cost five times the Python "
        f"around one solve. 1.6 x the monolithic solve is {1.6 * mono:.2f} s: "
        f"{glued - 1.6 * mono:.2f} s ({1e6 * (glued - 1.6 * mono) / stats['steps']:.0f} us "
        f"per step) less than the glued run, while everything that is not finite-element "
        f"work (the FMUs' Python around the solves, the crossings and the master: "
        f"{total_us - work_us:.0f} us per step above) would have to go down to "
        f"{max(total_us - work_us - 1e6 * (glued - 1.6 * mono) / stats['steps'], 0.0):.0f} "
        "us per step. "
        "None of it is physics, and it is spread thin: a crossing costs about "
        f"{list(budget['per_step_us'].values())[3] / calls_per_step:.1f} us per FMI call, a "
        "trial's Python in the FMU is a dozen small numpy operations, a Newton iteration's "
        "in the master a few sparse products and reductions; each lever tried on them "
        "moved the run by 0 to 9% (below). Closing the gap would take fewer FMI calls than "
        "a glued step needs (two trials, a save and a restore per part), an FMU whose step "
        "is not Python behind pythonfmu's boundary, or other bits in the result (the "
        "order of the floating-point operations of the solves and the repeated step is "
        "what keeps every scene byte-identical to its baseline).",
        "", "History: 15.6 (every doStep refactored the Newmark matrix for last-bit step "
        "differences), then 6 to 8 (one variable at a time through pythonfmu's getters and "
        "setters, outputs recomputed after every step and restore, numpy dispatch), then "
        "3.02 (two full Newmark solves per part per step), then 2.42 (the repeated step by "
        "the linear response, on a busier machine), then 2.28, then 2.06 (2026-11-27, on a "
        "CPU with AVX-512: floor 1.34 x), and the ratio above on the CPU named at the top. "
        "The ratio depends on the CPU: on an AMD EPYC the same code gave 2.81 with a floor "
        "of 1.59 x (2026-11-27), its monolithic solve 2.5 times and the glued run 3.5 "
        "times slower than on the AVX-512 machine, the Python around each solve costing "
        "relatively more there. "
        + LEVERS,
        "", "Profile of a 0.05 s glued run (sorted by own time):", "", "```",
        profile.strip(), "```", "",
        "## Craig-Bampton (rail_left, forced at its three port edges)", "",
        f"rail_left with a 25 Hz force of 100 N (y) on each of its 15 port nodes, "
        f"{CB_STEPS} steps of 1e-4 s; the error is `craig_bampton_error`: max over time of "
        "the interface displacement error relative to the full model's peak, and the "
        "largest relative error of the lowest four natural frequencies. Time per step: "
        "ElasticBody.step alone.", "",
        "| modes | coordinates | response error | frequency error | ms per step |",
        "|---|---|---|---|---|",
    ]
    for row in table:
        lines.append(f"| {row['modes']} | {row['coordinates']} | {row['response']:.2e} | "
                     f"{row['frequency']:.2e} | {row['step_ms']:.3f} |")
    text = "\n".join(lines) + "\n"
    path.write_text(text)
    return text


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--stop", type=float, default=frame.STOP_TIME)
    print(write_report(parser.parse_args().stop))
