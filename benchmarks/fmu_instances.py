"""Memory and set-up time per instance of dsim's pythonfmu FMUs, two builds side by side.

Each measurement is a fresh process that makes ``small`` then ``large`` instances of one
FMU with its default parameters, the way a run makes them (``open_subsystem``: fmpy
instance sharing its FMU file's library binding, fmi2Instantiate, set-up, initialization
mode; Python's garbage collector paused), then leaves initialization mode in every one
(the model's core is built).  Per instance, from the slope between ``small`` and
``large`` (what every run pays once is not in it): resident size, tracemalloc's traced
memory (a second process: tracing slows the calls), CPU seconds of open_subsystem;
then per instance, the resident size and CPU seconds of leaving initialization mode.
It also counts, after ``large`` instances, the model classes and pythonfmu variable
objects alive in the process.  The two builds run in turn, the least of the
repetitions is kept (the machine is shared).

    python -m benchmarks.fmu_instances --before OLD/build/fmus --after build/fmus
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: one build's FMU, instantiated ``small`` then ``large`` times in this child process
_CHILD = """
import gc, json, os, sys, time, tracemalloc
from pathlib import Path
from pythonfmu import Fmi2Slave
from dsim.master.running.fmi import SubsystemSpec, open_subsystem

path, small, large = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
trace = sys.argv[4] == "1"
model = path.stem
page = os.sysconf("SC_PAGE_SIZE")

def resident():
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * page

def spec(i):
    return SubsystemSpec(name=f"c{i}", path=path, port_dofs=(), parameters={}, reads=(),
                         writes=(), start_time=0.0, stop_time=1.0)

def counts():
    objects = gc.get_objects()
    return {"classes": sum(isinstance(o, type) and o.__name__ == model
                               and issubclass(o, Fmi2Slave) for o in objects),
            "variables": sum(type(o).__module__ == "pythonfmu.variables" for o in objects)}

warm = open_subsystem(spec("warm"))  # imports, the library, the extracted FMU
warm.finish_initialization()
gc.collect()
gc.disable()
if trace:
    tracemalloc.start()
instances, cpu, marks = [], 0.0, {}
for i in range(large):
    start = time.process_time()
    instances.append(open_subsystem(spec(i)))
    cpu += time.process_time() - start
    if i + 1 in (small, large):
        gc.collect()
        marks[i + 1] = {"cpu": cpu, "resident": resident(),
                        "traced": tracemalloc.get_traced_memory()[0] if trace else 0}
counted = counts()
gc.collect()
before, start = resident(), time.process_time()
for instance in instances:
    instance.finish_initialization()
initialize_cpu = time.process_time() - start
gc.collect()
initialized = resident() - before
a, b = marks[small], marks[large]
n = large - small
print(json.dumps({"resident": (b["resident"] - a["resident"]) / n,
                  "traced": (b["traced"] - a["traced"]) / n,
                  "cpu": (b["cpu"] - a["cpu"]) / n, **counted,
                  "initialize_resident": initialized / large,
                  "initialize_cpu": initialize_cpu / large}))
"""


def measure(fmu: Path, small: int, large: int, trace: bool) -> dict:
    """One child process's figures per instance of ``fmu`` (bytes, CPU seconds)."""
    found = subprocess.run([sys.executable, "-c", _CHILD, str(fmu), str(small), str(large),
                            "1" if trace else "0"], capture_output=True, text=True,
                           cwd=ROOT, env={**os.environ, "OMP_NUM_THREADS": "1"})
    if found.returncode:
        raise RuntimeError(f"{fmu}: {found.stderr[-2000:]}")
    return json.loads(found.stdout.strip().splitlines()[-1])


def compare(builds: dict, models, small: int, large: int, repetitions: int) -> dict:
    """model -> build label -> the least of each figure over the repetitions, the two
    builds measured in turn."""
    least: dict = {}
    for _ in range(repetitions):
        for model in models:
            for label, folder in builds.items():
                fmu = Path(folder) / f"{model}.fmu"
                run = measure(fmu, small, large, trace=False)
                run["traced"] = measure(fmu, small, large, trace=True)["traced"]
                kept = least.setdefault(model, {}).setdefault(label, run)
                for key, value in run.items():
                    kept[key] = min(kept[key], value)
                print(model, label, json.dumps(run), file=sys.stderr, flush=True)
    return least


def table(least: dict, small: int, large: int) -> str:
    """The comparison as a markdown table."""
    lines = [f"| FMU | build | resident (kB / instance) | traced (kB / instance) | "
             f"open_subsystem CPU (ms / instance) | model classes after {large} | "
             f"pythonfmu variables after {large} | initialization: resident (kB) | "
             f"CPU (ms) |", "|---|---|---|---|---|---|---|---|---|"]
    for model, builds in least.items():
        for label, r in builds.items():
            lines.append(f"| {model} | {label} | {r['resident'] / 1024:.1f} | "
                         f"{r['traced'] / 1024:.1f} | {r['cpu'] * 1e3:.2f} | "
                         f"{r['classes']} | {r['variables']} | "
                         f"{r['initialize_resident'] / 1024:.0f} | "
                         f"{r['initialize_cpu'] * 1e3:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> str:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", required=True, help="a folder of built FMUs")
    parser.add_argument("--after", default=str(ROOT / "build" / "fmus"))
    parser.add_argument("--models", default="ElasticBody,Linkage2D,FlexibleLink2D")
    parser.add_argument("--small", type=int, default=50)
    parser.add_argument("--large", type=int, default=200)
    parser.add_argument("--repetitions", type=int, default=3)
    args = parser.parse_args(argv)
    least = compare({"before": args.before, "after": args.after}, args.models.split(","),
                    args.small, args.large, args.repetitions)
    text = table(least, args.small, args.large)
    print(text)
    return text


if __name__ == "__main__":
    main()
