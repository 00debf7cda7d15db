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
    parser.add_argument("--docs", default=str(ROOT / "docs" / "scaling.md"))
    args = parser.parse_args(argv)
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
        ""])
    Path(args.docs).write_text(text)
    return text


if __name__ == "__main__":
    print(main())
