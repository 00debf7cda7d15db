"""How dsim grows with the number of subsystems: chains of n SpringMass FMUs glued by
fixed joints (``build_fmus/scenes.py`` ``chain(n)``, one FMU file used by every
component).

For 10, 100, 1,000 and 10,000 subsystems: set-up (reading, planning, instantiating and
initialising every FMU, the start forces), wall time per macro step, per step per
subsystem, and the peak memory of the process; for 1,000 to 100,000 components: ``dsim
validate`` and ``dsim info`` (its output thrown away), wall and CPU seconds and peak
memory.  Every measurement runs in a fresh process, so that the peak memory is that
run's; the CPU seconds say what a run costs when other work shares the machine (its
wall seconds then include waiting for a core).

    python -m benchmarks.scaling            # writes docs/scaling.md
    python -m benchmarks.scaling --only ray --calm 1.6   # its Ray section only
"""
from __future__ import annotations

import argparse
import json
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FMU = ROOT / "build" / "fmus" / "SpringMass.fmu"

#: a run in a child process: its statistics, its CPU seconds and peak memory, as JSON
_RUN = """
import json, resource, sys, time
import dsim
import dsim.master.api  # imported before the clock starts (dsim imports it when first used)
from dsim.master.recording.observers import Observer

class Clock(Observer):
    # CPU seconds at the first row (set-up done) and at the last
    marks = []
    def stepped(self, record):
        self.marks[1:] = [time.process_time()] if self.marks else []
        if not self.marks:
            self.marks.append(time.process_time())

clock = Clock()
begun = time.process_time()
result = dsim.simulate(sys.argv[1], stop=float(sys.argv[2]), handle_signals=False,
                       observers=[clock])
usage = resource.getrusage(resource.RUSAGE_SELF)
s = result.statistics
print(json.dumps({"status": s["status"], "steps": s["steps"], "wall": s["wall_seconds"],
                  "setup": s["setup_seconds"], "setup_cpu": clock.marks[0] - begun,
                  "steps_cpu": clock.marks[1] - clock.marks[0],
                  "cpu": usage.ru_utime + usage.ru_stime, "peak_mb": usage.ru_maxrss / 1024}))
"""


#: set-up of one chain in-process and on a local Ray instance, in turn in one process;
#: one run of each first, not measured: its processes are those Ray starts with the
#: instance, and a process's first run loads what later ones find loaded, so that every
#: measured Ray run starts its worker processes from nothing; before each measured pair,
#: the machine's ceiling (benchmarks/ray_speedup.py: what two processes gain over one
#: now), once it has reached the calm asked for
_RAY = """
import json, os, sys
from pathlib import Path
import ray
import dsim
import dsim.master.api
from benchmarks.ray_speedup import ceiling_now
ray.init(address="local", num_cpus=os.cpu_count(), include_dashboard=False,
         log_to_driver=False, logging_level="ERROR")
setup, rows, ceilings = {"in-process": [], "ray": []}, {}, []
for repetition in range(-1, int(sys.argv[2])):
    if repetition >= 0:
        ceilings.append(ceiling_now(float(sys.argv[4])))
    for backend in setup:
        out = Path(sys.argv[3]) / f"{backend}-{repetition}.csv"
        result = dsim.simulate(sys.argv[1], stop=5e-3, backend=backend, out=out,
                               handle_signals=False)
        assert result.statistics["status"] == "completed", result.statistics
        if repetition >= 0:
            setup[backend].append(result.statistics["setup_seconds"])
        rows.setdefault(backend, out.read_bytes())
print(json.dumps({"setup": setup, "identical": rows["ray"] == rows["in-process"],
                  "cpus": os.cpu_count(), "ray_version": ray.__version__,
                  "ceilings": ceilings, "calm": float(sys.argv[4])}))
"""


def ray_setup(n: int, folder: Path, repetitions: int = 5, calm: float = 0.0) -> dict:
    """Set-up seconds (``setup_seconds``) of chain_n in-process and on a local Ray
    instance (one worker per CPU), in turn ``repetitions`` times in one fresh process
    (after one run of each that is not measured), whether the two runs' results are
    the same bytes, and the machine's ceiling before each pair (with ``calm`` > 0,
    each pair waits until the ceiling reaches it, ten minutes at most)."""
    found = subprocess.run([sys.executable, "-c", _RAY, str(chain_folder(n, folder / "scene")),
                            str(repetitions), str(folder), str(calm)],
                           capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(found.stdout.strip().splitlines()[-1])


def ray_lines(n: int, result: dict) -> list[str]:
    """The page's paragraphs on set-up with Ray."""
    local, ray = result["setup"]["in-process"], result["setup"]["ray"]
    ratios = [r / l for l, r in zip(local, ray)]
    faster = sum(ratio < 1 for ratio in ratios)
    cpus = result["cpus"]
    return [
        RAY_HEADING, "",
        f"chain_{n}, five macro steps, set up in-process and on a local Ray instance "
        f"(Ray {result.get('ray_version', '?')}, {cpus} CPUs: {cpus} workers, each "
        f"instantiating its share of the FMUs at the same time) in turn, {len(local)} "
        "times in one process, after one run of each that is not measured "
        "(`python -m benchmarks.scaling --only ray"
        + (f" --calm {result['calm']:g}" if result.get("calm") else "")
        + f"`, {date.today()}). Set-up is the run's "
        "`setup_seconds`, for both backends from the start of the run (the scene read and "
        "planned) to its first row: for Ray that is connecting, choosing the nodes, "
        "starting the worker processes (every measured run starts new ones: Python, Ray, "
        "dsim's worker module), shipping the FMU, instantiating and initialising every "
        "FMU, and the start forces.", "",
        "| backend | set-up, least (s) | each run (s) |", "|---|---|---|",
        f"| in-process | {min(local):.2f} | {', '.join(f'{x:.2f}' for x in local)} |",
        f"| Ray | {min(ray):.2f} | {', '.join(f'{x:.2f}' for x in ray)} |",
        "| the machine's ceiling before each pair: 2 busy processes against 1 | | "
        f"{', '.join(f'{x:.2f}' for x in result['ceilings'])} |", "",
        f"Ray / in-process, run by run: {', '.join(f'{x:.2f}' for x in ratios)} (Ray "
        f"faster in {faster} of {len(ratios)}); least against least: "
        f"{min(ray) / min(local):.2f}. Results identical to the byte: "
        f"{'yes' if result['identical'] else 'NO'}.", "",
        "The machine is shared: the **ceiling** is how much faster two processes do two "
        "equal pieces of CPU work than one process does them in turn, measured before "
        "each pair (`benchmarks/ray_speedup.py`; 2.0 on an idle 2-core machine, less "
        "while other work holds a core): two workers cannot instantiate faster than it "
        "allows, so read each ratio against its pair's ceiling" + (
            f"; each pair waited for a ceiling of {result['calm']:g} (`--calm`, ten "
            "minutes at most)." if result.get("calm") else "."), "",
        RAY_NOTES, ""]


#: where a Ray set-up's time goes, measured on these machines (not by this script)
RAY_NOTES = (
    "Where a Ray set-up's time goes (chain_1000, two workers, measured apart on these "
    "machines): a new worker process takes 0.3 to 1.5 s to start and import dsim's "
    "worker module, depending on what else holds the cores; most of it is Ray starting "
    "a Python process (an actor that does nothing takes 0.8 to 1.5 s to answer its "
    "first call while other work holds the cores), the module itself takes 0.09 s with "
    "Ray loaded: it no longer imports scipy, whose integrate package alone took 0.4 s "
    "and only a Model Exchange FMU's step needs. Each worker's 500 SpringMass instances "
    "take 0.8 s of CPU to instantiate, as in-process (1.6 ms each, most of it in the "
    "FMU's fmi2Instantiate); the initialisation, six calls answered by every worker, "
    "about 0.3 s, against 0.45 s in-process. The workers instantiate at the same time, "
    "one remote call each, sent to every worker before any answer is awaited, with "
    "Python's garbage collector paused; then a worker freezes its instances out of the "
    "collector (`gc.freeze`: each collector pass over 500 instances' 440,000 objects "
    "took 0.1 s of CPU, and the first passes fell on the run's first calls). The FMU "
    "is put in Ray's object store once per run, and each worker lands it once per "
    "file (on the driver's machine it uses the driver's file). Not done, measured: "
    "starting the workers before the scene is read and planned would hide at most "
    "that, 0.16 to 0.19 s at chain_1000, and would take the workers' start out of "
    "`setup_seconds`; batching the initialisation's calls into fewer round trips would "
    "save about 13 ms a round trip (its calls depend on what the driver computes in "
    "between). With two cores the workers save at most half of the instantiation "
    "(0.8 s) while their start is added: Ray is ahead when the machine's two cores are "
    "free (a ceiling near 2), and behind when other work holds one (a ceiling near 1, "
    "where two processes gain nothing over one: in a run of this script on 2026-11-27 "
    "without `--calm`, ceilings 0.71 to 0.96, Ray was behind in all five pairs, its "
    "least 2.34 s against 2.17 s). With more cores per machine, or more "
    "machines, the instantiation divides further while the start of the workers does "
    "not grow.")


RAY_HEADING = "## Set-up on a local Ray cluster"

#: what the tables rest on, said under them
NOTES = (
    "What keeps these linear: components, ports and joints are found by name through "
    "indices made once (a scan per look-up made validating 10,000 components take a "
    "minute); everything that depends only on an FMU file (its SHA-256, model "
    "description, ports, capability checks) is computed once per file, and a system's "
    "annotations once per system; the gluing incidence is built as one sparse matrix; "
    "Python's cyclic garbage collector is paused while a scene is read, planned and "
    "instantiated (its passes over millions of young objects cost as much as the work). "
    "Every instance of one FMU file shares one binding of its library's functions "
    "(`dsim.master.running.fmi.library`: fmpy bound them again for each instance, 6 ms "
    "apiece). What is left of the set-up is each instance's own start-up: the "
    "SpringMass FMU is a pythonfmu FMU, whose instance builds its Python model and "
    "registers its variables (about 2 ms), and whose Python objects are most of the "
    "memory of a large chain (about 170 kB per instance). The time per step per "
    "subsystem grows from 100 to 10,000 subsystems although every step's work is linear "
    "(the profile of a chain_1000 step is the FMUs' own code and one call per FMI "
    "function per subsystem): thousands of Python FMU instances no longer fit the "
    "processor's caches.")


def chain_folder(n: int, folder: Path) -> Path:
    """A chain of ``n`` subsystems as a scene folder (the FMU in its resources)."""
    from dsim.build_fmus.scenes import CHAIN, chain

    chain(n).write(folder, 0.0, CHAIN["stop"], step=CHAIN["step"], tolerance=1e-13,
                   maxIterations=20, predictor="linear", refreshAfter=10)
    (folder / "resources").mkdir(exist_ok=True)
    shutil.copy(FMU, folder / "resources" / FMU.name)
    return folder


def run(folder: Path, steps: int) -> dict:
    """One run of ``steps`` macro steps in a fresh process."""
    found = subprocess.run([sys.executable, "-c", _RUN, str(folder), str(steps * 1e-3)],
                           capture_output=True, text=True, check=True)
    result = json.loads(found.stdout.strip().splitlines()[-1])
    result["per_step"] = (result["wall"] - result["setup"]) / result["steps"]
    result["per_step_cpu"] = result["steps_cpu"] / result["steps"]
    return result


#: one dsim command in a child process; its CPU seconds and peak memory to stderr
_COMMAND = """
import json, resource, sys
from dsim.master.tools.cli import main
code = main(sys.argv[1:])
usage = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"code": code, "cpu": usage.ru_utime + usage.ru_stime,
                  "peak_mb": usage.ru_maxrss / 1024}), file=sys.stderr)
"""


def command(*args) -> dict:
    """Wall seconds, CPU seconds and peak memory of one ``dsim`` command (output dropped)."""
    start = time.perf_counter()
    found = subprocess.run([sys.executable, "-c", _COMMAND, *map(str, args)],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - start
    result = json.loads(found.stderr.strip().splitlines()[-1])
    if result["code"]:
        raise RuntimeError(f"dsim {' '.join(map(str, args))}: {found.stderr.strip()}")
    return {"wall": wall, "cpu": result["cpu"], "peak_mb": result["peak_mb"]}


def main(argv=None) -> str:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", default="10,100,1000,10000", help="subsystems per run")
    parser.add_argument("--steps", default="200,50,20,10",
                        help="macro steps of each run (whole tens: one flexibility refresh "
                        "in ten steps for every chain)")
    parser.add_argument("--checks", default="1000,10000,100000",
                        help="components of the validate and info scenes")
    parser.add_argument("--ray", type=int, default=1000,
                        help="subsystems of the set-up in-process vs Ray (0: none)")
    parser.add_argument("--calm", type=float, default=0.0,
                        help="before each pair of the Ray set-up, wait until the machine's "
                        "ceiling (2 processes against 1) reaches this (0: do not wait)")
    parser.add_argument("--only", choices=["ray"],
                        help="measure only this and replace its section of the page")
    parser.add_argument("--docs", default=str(ROOT / "docs" / "scaling.md"))
    args = parser.parse_args(argv)
    ray_text: list[str] = []
    if args.ray:
        with tempfile.TemporaryDirectory(prefix="dsim-scaling-") as temp:
            result = ray_setup(args.ray, Path(temp), calm=args.calm)
        print(f"ray chain_{args.ray}: {result}", flush=True)
        ray_text = ray_lines(args.ray, result)
    if args.only == "ray":
        page = Path(args.docs).read_text()
        kept = page.split(RAY_HEADING)[0].rstrip("\n")
        text = "\n".join([kept, "", *ray_text])
        Path(args.docs).write_text(text)
        return text
    runs, checks = [], []
    with tempfile.TemporaryDirectory(prefix="dsim-scaling-") as temp:
        for n, steps in zip(map(int, args.runs.split(",")), map(int, args.steps.split(","))):
            result = run(chain_folder(n, Path(temp) / f"chain_{n}"), steps)
            runs.append((n, result))
            print(f"chain_{n}: {result}", flush=True)
            shutil.rmtree(Path(temp) / f"chain_{n}")
        for n in map(int, args.checks.split(",")):
            folder = chain_folder(n, Path(temp) / f"chain_{n}")
            checks.append((n, command("validate", folder), command("info", folder)))
            print(f"validate/info chain_{n}: {checks[-1][1:]}", flush=True)
            shutil.rmtree(folder)
    base = next((r["per_step_cpu"] / n for n, r in runs if n == 100), None)
    lines = ["| subsystems | macro steps | set-up: wall (s) | CPU (s) | per macro step: wall "
             "(ms) | CPU (ms) | CPU per step per subsystem (ms) | / chain_100's | peak "
             "memory (MB) |", "|---|---|---|---|---|---|---|---|---|"]
    for n, r in runs:
        each = r["per_step_cpu"] / n
        lines.append(f"| {n} | {r['steps']} | {r['setup']:.2f} | {r['setup_cpu']:.2f} | "
                     f"{r['per_step'] * 1e3:.1f} | {r['per_step_cpu'] * 1e3:.1f} | "
                     f"{each * 1e3:.3f} | " + (f"{each / base:.2f}" if base else "-")
                     + f" | {r['peak_mb']:.0f} |")
    check_lines = ["| components | validate: wall (s) | CPU (s) | peak memory (MB) | "
                   "info: wall (s) | CPU (s) | peak memory (MB) |",
                   "|---|---|---|---|---|---|---|"]
    for n, v, i in checks:
        check_lines.append(f"| {n} | {v['wall']:.1f} | {v['cpu']:.1f} | {v['peak_mb']:.0f} | "
                           f"{i['wall']:.1f} | {i['cpu']:.1f} | {i['peak_mb']:.0f} |")
    text = "\n".join([
        "# Scaling: ten to a hundred thousand subsystems",
        "",
        f"Written by `python -m benchmarks.scaling` on {date.today()} ({platform.machine()}, "
        f"Python {platform.python_version()}, in-process backend). Chains of n SpringMass "
        "FMUs (pythonfmu, one FMU file shared by every component) glued in a line by fixed "
        "joints (`build_fmus/scenes.py`, `chain(n)`), each measured in a fresh process. "
        "Set-up is reading, planning, instantiating and initialising every FMU and the "
        "start forces: wall, the run's `setup_seconds`; CPU, from calling `dsim.simulate` "
        "to the first row. Per macro step is the rest of the run over its steps (a "
        "refresh of the interface flexibility every 10 steps included), wall and CPU; "
        "peak memory is the process's maximum resident size. The machine is shared with "
        "other work (two cores): wall seconds include waiting for a core, CPU seconds "
        "are what the run costs.",
        "",
        *lines,
        "",
        "`dsim validate` and `dsim info` (its output written to /dev/null) of chains of "
        "1,000 to 100,000 components, each in a fresh process (about 0.6 s of it is "
        "Python importing dsim):",
        "",
        *check_lines,
        "",
        NOTES,
        "",
        *ray_text])
    Path(args.docs).write_text(text)
    return text


if __name__ == "__main__":
    print(main())
