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
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from datetime import date
from pathlib import Path

from benchmarks import machine

ROOT = Path(__file__).resolve().parent.parent
FMU = ROOT / "build" / "fmus" / "SpringMass.fmu"

#: a run in a child process: its statistics, its CPU seconds and peak memory, as JSON
_RUN = """
import json, resource, sys, time
import dsim
import dsim.master.api  # imported before the clock starts (dsim imports it when first used)
from dsim.master.recording.observers import Observer

class Clock(Observer):
    # CPU seconds at every row: the first is the end of the set-up
    marks = []
    def stepped(self, record):
        self.marks.append(time.process_time())

clock = Clock()
begun = time.process_time()
result = dsim.simulate(sys.argv[1], stop=float(sys.argv[2]), handle_signals=False,
                       observers=[clock])
usage = resource.getrusage(resource.RUSAGE_SELF)
s = result.statistics
print(json.dumps({"status": s["status"], "steps": s["steps"], "wall": s["wall_seconds"],
                  "setup": s["setup_seconds"], "setup_cpu": clock.marks[0] - begun,
                  "marks": clock.marks,
                  "cpu": usage.ru_utime + usage.ru_stime, "peak_mb": usage.ru_maxrss / 1024}))
"""


#: set-up of one chain in-process and on a local Ray instance, in turn in one process;
#: one run of each first, not measured: its processes are those Ray starts with the
#: instance, and a process's first run loads what later ones find loaded.  Ray three
#: ways: no spare kept (the workers started as the run begins: the first run of a
#: script on its Ray instance), the next run at once (the spares the run before left,
#: still starting), and once those spares are ready (ray_spares.py); each run's
#: ``setup_seconds`` and the wall time from the call of dsim.simulate to the first row
#: (reading and planning included, and whatever Ray starts meanwhile); before each
#: measured round, the machine's ceiling (benchmarks/ray_speedup.py: what two processes
#: gain over one now), once it has reached the calm asked for
_RAY = """
import json, os, sys, time
from pathlib import Path
import ray
import dsim
import dsim.master.api
from dsim.master.recording.observers import Observer
from dsim.master.running.backends.ray import spares as ray_spares
from benchmarks.ray_speedup import ceiling_now
ray.init(address="local", num_cpus=os.cpu_count(), include_dashboard=False,
         log_to_driver=False, logging_level="ERROR")

class FirstRow(Observer):
    at = None
    def stepped(self, record):
        self.at = self.at or time.perf_counter()

kinds = ("in-process", "ray", "ray-next", "ray-ready")
setup, call, rows, ceilings = {k: [] for k in kinds}, {k: [] for k in kinds}, {}, []
for repetition in range(-1, int(sys.argv[2])):
    ray_spares.drop()
    if repetition >= 0:
        ceilings.append(ceiling_now(float(sys.argv[4])))
    for kind in kinds:
        if kind == "ray-ready":
            ray_spares.settle()
        out = Path(sys.argv[3]) / f"{kind}-{repetition}.csv"
        first, began = FirstRow(), time.perf_counter()
        result = dsim.simulate(sys.argv[1], stop=5e-3, backend=kind.split("-")[0]
                               if kind != "in-process" else kind, out=out,
                               handle_signals=False, observers=[first])
        assert result.statistics["status"] == "completed", result.statistics
        if repetition >= 0:
            setup[kind].append(result.statistics["setup_seconds"])
            call[kind].append(first.at - began)
        rows.setdefault(kind, out.read_bytes())
print(json.dumps({"setup": setup, "call": call, "identical": len(set(rows.values())) == 1,
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


#: the ways `dsim run` is timed from the command line, as the page names them
#: (its name, its options, its environment)
CLI_KINDS = {"in-process": ("in-process", [], {}),
             "cluster-none": ("`--backend ray --address` a running one-node cluster, no "
                              "spare (`DSIM_RAY_SPARES=0`)",
                              ["--backend", "ray", "--address", "{address}"],
                              {"DSIM_RAY_SPARES": "0"}),
             "cluster": ("the same, taking the spares the command a round before left",
                         ["--backend", "ray", "--address", "{address}"], {}),
             "cluster-next": ("the same again at once (the spares still starting)",
                              ["--backend", "ray", "--address", "{address}"], {}),
             "own": ("`--backend ray`, Ray started by the run", ["--backend", "ray"], {})}
#: the ways whose set-up the page compares with in-process's, round by round
CLI_COMPARED = ("cluster-none", "cluster", "cluster-next")


def cli_setup(n: int, folder: Path, repetitions: int = 5, calm: float = 0.0) -> dict:
    """``dsim run`` of chain_n from the command line, five macro steps, each way of
    :data:`CLI_KINDS` in turn ``repetitions`` times after one round not measured: the
    run's ``setup_seconds`` and the command's wall time (Python's start, reading,
    planning, set-up, the steps and the end, Ray's included), on a one-node cluster
    this function starts (`ray start --head`, one CPU per core) and ends."""
    import secrets
    import socket

    from benchmarks.ray_speedup import ceiling_now

    scene = chain_folder(n, folder / "scene")
    dsim = str(Path(sys.executable).parent / "dsim")
    ray_cli = str(Path(sys.executable).parent / "ray")
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0", "OMP_NUM_THREADS": "1",
           "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    temp = Path(tempfile.mkdtemp(prefix="dsimh", dir="/tmp"))  # short: socket paths
    log = temp / "head.log"
    head = subprocess.Popen([ray_cli, "start", "--head", f"--port={port}", "--block",
                             f"--num-cpus={os.cpu_count()}", "--include-dashboard=false",
                             f"--temp-dir={temp}"], env=env, stdout=open(log, "w"),
                            stderr=subprocess.STDOUT, start_new_session=True)
    setup = {kind: [] for kind in CLI_KINDS}
    wall = {kind: [] for kind in CLI_KINDS}
    ceilings, rows = [], {}
    try:
        address = f"127.0.0.1:{port}"
        deadline = time.monotonic() + 120
        while "block forever" not in log.read_text():
            if time.monotonic() > deadline or head.poll() is not None:
                raise RuntimeError(f"the benchmark's Ray head did not start: "
                                   f"{log.read_text()}")
            time.sleep(0.2)
        for repetition in range(-1, repetitions):
            if repetition >= 0:
                ceilings.append(ceiling_now(calm))
            for kind, (_, options, extra) in CLI_KINDS.items():
                out = folder / f"cli-{kind}-{repetition}.csv"
                began = time.perf_counter()
                subprocess.run([dsim, "run", str(scene), "--stop", "5e-3", "--quiet",
                                "--out", str(out),
                                *(o.format(address=address) for o in options)],
                               env={**env, **extra}, check=True, stderr=subprocess.DEVNULL,
                               cwd=folder)
                took = time.perf_counter() - began
                if repetition >= 0:
                    said = json.loads(out.with_suffix(".stats.json").read_text())
                    setup[kind].append(said["setup_seconds"])
                    wall[kind].append(took)
                rows.setdefault(kind, out.read_bytes())
    finally:
        for number in (signal.SIGTERM, signal.SIGKILL):  # the head's process group
            try:
                os.killpg(head.pid, number)
                head.wait(10)
                break
            except subprocess.TimeoutExpired:
                continue
            except ProcessLookupError:
                break
        shutil.rmtree(temp, ignore_errors=True)
    return {"setup": setup, "wall": wall, "ceilings": ceilings,
            "identical": len(set(rows.values())) == 1}


def cli_lines(n: int, result: dict) -> list[str]:
    """The page's paragraph and table on `dsim run` with Ray from the command line."""
    def cells(values) -> str:
        return f"{min(values):.2f} | {', '.join(f'{x:.2f}' for x in values)}"

    local = result["setup"]["in-process"]
    rounds = len(local)
    lines = [
        "### `dsim run` from the command line", "",
        f"chain_{n}, five macro steps, `dsim run` from the command line each way in turn, "
        f"{rounds} rounds after one not measured (`python -m benchmarks.scaling --only "
        "ray`). Each command is a new process. Given a running cluster's address, it "
        "joins the cluster before it reads and plans the scene "
        "(`ray_cluster.connect_ahead`), meanwhile claims the spare workers an earlier "
        "command left in the cluster and starts the others it needs, and as it ends "
        "leaves as many fresh spares there for the next command (`ray_pool.py`; "
        "`DSIM_RAY_SPARES=0` turns that off: the first row of the cluster's); without "
        "an address it starts a Ray instance of its own, and ends it as it ends. The "
        "command's wall time includes Python's start, reading and planning, the five "
        "steps and the end (Ray's shutdown included).", "",
        "| `dsim run` | set-up, least (s) | each round (s) | the command's wall time, least "
        "(s) | each round (s) |", "|---|---|---|---|---|"]
    for kind, (name, _, _) in CLI_KINDS.items():
        lines.append(f"| {name} | {cells(result['setup'][kind])} | "
                     f"{cells(result['wall'][kind])} |")
    compared = []
    for kind in CLI_COMPARED:
        cluster = result["setup"][kind]
        compared.append(
            f"{CLI_KINDS[kind][0]}: "
            f"{', '.join(f'{c / l:.2f}' for l, c in zip(local, cluster))} (faster in "
            f"{sum(c < l for l, c in zip(local, cluster))} of {rounds}; least against "
            f"least {min(cluster) / min(local):.2f})")
    lines += ["", f"Set-up against in-process, round by round: {'; '.join(compared)}; the "
              f"machine's ceiling before each round: "
              f"{', '.join(f'{x:.2f}' for x in result['ceilings'])}. "
              f"Results identical to the byte: {'yes' if result['identical'] else 'NO'}.",
              ""]
    return lines


#: the Ray set-ups measured, as the page names them
RAY_KINDS = {"ray": "Ray, no spare kept (workers started as the run begins)",
             "ray-next": "Ray, the next run at once (spares still starting)",
             "ray-ready": "Ray, spares ready"}


def ray_lines(n: int, result: dict, commands: dict | None = None) -> list[str]:
    """The page's paragraphs on set-up with Ray (``commands``: :func:`cli_setup`'s)."""
    local, local_call = result["setup"]["in-process"], result.get("call", {}).get("in-process")
    cpus = result["cpus"]

    def cells(values) -> str:
        return f"{min(values):.2f} | {', '.join(f'{x:.2f}' for x in values)}"

    table, ratios = [], []
    for kind, name in RAY_KINDS.items():
        ray = result["setup"][kind]
        ratio = [r / l for l, r in zip(local, ray)]
        row = f"| {name} | {cells(ray)} |"
        said = (f"{name}: {', '.join(f'{x:.2f}' for x in ratio)} (Ray faster in "
                f"{sum(x < 1 for x in ratio)} of {len(ratio)}; least against least "
                f"{min(ray) / min(local):.2f}")
        if local_call:
            ray_call = result["call"][kind]
            row += f" {cells(ray_call)} |"
            said += (f"; from the call, Ray faster in "
                     f"{sum(r < l for l, r in zip(local_call, ray_call))} of "
                     f"{len(ray_call)}, least against least "
                     f"{min(ray_call) / min(local_call):.2f}")
        table.append(row)
        ratios.append(said + ")")
    head = "| backend | set-up, least (s) | each round (s) |"
    rule = "|---|---|---|"
    first = f"| in-process | {cells(local)} |"
    ceiling = "| the machine's ceiling before each round: 2 busy processes against 1 | | "
    if local_call:
        head += " from the call to the first row, least (s) | each round (s) |"
        rule += "---|---|"
        first += f" {cells(local_call)} |"
    return [
        RAY_HEADING, "",
        f"chain_{n}, five macro steps, set up in-process and on a local Ray instance "
        f"(Ray {result.get('ray_version', '?')}, {cpus} CPUs: {cpus} workers, each "
        f"instantiating its share of the FMUs at the same time) in turn, {len(local)} "
        "rounds in one process, after one round that is not measured "
        "(`python -m benchmarks.scaling --only ray"
        + (f" --calm {result['calm']:g}" if result.get("calm") else "")
        + f"`, {date.today()}). Set-up is the run's "
        "`setup_seconds`, for both backends from the start of the run (the scene read and "
        "planned) to its first row: for Ray that is connecting, choosing the nodes, "
        "taking or starting the worker processes, shipping the FMU, instantiating and "
        "initialising every FMU, and the start forces; from the call is the wall time "
        "from calling `dsim.simulate` to the first row, the reading and planning "
        "included, and with them whatever Ray starts meanwhile. Each round runs "
        "in-process, then "
        "on Ray three times: with no spare worker kept (every worker a new process: "
        "Python, Ray, dsim's worker module, started as the run begins, before the scene "
        "is read and planned, as in the first run of a script on its Ray instance), then at once again (taking the spares the run before started "
        "as it ended: docs/distributed.md, \"Spare workers\"), then once the spares the "
        "second run left have started. The second run's set-up shares the two cores with "
        "the end of the run before (its workers freeing their 500 FMU instances each) and "
        "with its spares' start: what a script that runs scenes back to back meets (measured "
        "apart on 2026-11-27, 5 pairs in turn, each after a pause: such a run set up in "
        "0.64 to 0.71 s with spares and 0.72 to 0.81 s with them switched off).", "",
        head, rule, first, *table,
        ceiling + f"{', '.join(f'{x:.2f}' for x in result['ceilings'])} |"
        + (" | |" if local_call else ""), "",
        "Ray / in-process, round by round: " + "; ".join(ratios) + ". Results identical "
        f"to the byte: {'yes' if result['identical'] else 'NO'}.", "",
        "The machine is shared: the **ceiling** is how much faster two processes do two "
        "equal pieces of CPU work than one process does them in turn, measured before "
        "each round (`benchmarks/ray_speedup.py`; 2.0 on an idle 2-core machine, less "
        "while other work holds a core): two workers cannot instantiate faster than it "
        "allows, so read each ratio against its round's ceiling" + (
            f"; each round waited for a ceiling of {result['calm']:g} (`--calm`, ten "
            "minutes at most)." if result.get("calm") else "."), "",
        *(cli_lines(n, commands) if commands else []),
        *RAY_NOTES, ""]


#: where a Ray set-up's time goes, measured on these machines (not by this script)
RAY_NOTES = (
    "Where a Ray set-up's time goes (chain_1000, two workers, measured apart on these "
    "machines): a new worker process takes 0.3 to 1.5 s to start and import dsim's "
    "worker module, depending on what else holds the cores; most of it is Ray starting "
    "a Python process (an actor that does nothing takes 0.8 to 1.5 s to answer its "
    "first call while other work holds the cores), the module itself takes 0.09 s with "
    "Ray loaded: it no longer imports scipy, whose integrate package alone took 0.4 s "
    "and only a Model Exchange FMU's step needs. The workers instantiate at the same "
    "time, one remote call each, sent to every worker before any answer is awaited, "
    "with Python's garbage collector paused; then a worker freezes its instances out "
    "of the collector (`gc.freeze`), as the in-process backend does. The FMU is put in "
    "Ray's object store once per run, and each worker lands it once per file (on the "
    "driver's machine it uses the driver's file); a batch of calls travels as one "
    "pickle of Python's C pickler and its answer comes back the same way (Ray's own "
    "serialization dispatches each of thousands of arrays in Python), and what the "
    "driver keeps of it for a lost worker is that pickle's bytes, looked into only when "
    "a worker is lost (`copy.deepcopy` of every batch took 0.8 s of a chain_4000's run, "
    "loading them back and sorting their calls took the driver 0.09 to 0.1 s of CPU a "
    "step of chain_10000). Starting the workers before the scene is read "
    "and planned (a script's run on its own Ray instance, `ray_spares.ahead`) hides "
    "part of their start behind that, 0.16 to 0.19 s at chain_1000, and out of "
    "`setup_seconds`, which begins after the plan: hence the table's second pair of "
    "columns, from the call. Not done, measured: batching "
    "the initialisation's calls into fewer round trips would save about 13 ms a round "
    "trip (its calls depend on what the driver computes in between); keeping a run's "
    "workers for the next run of the same driver process would take their start out of "
    "later set-ups, but the FMU code of one run (a pythonfmu FMU runs its Python in the "
    "worker's interpreter) would live on in the process that hosts the next run's FMUs, "
    "and separate processes per run are what the Ray and isolated backends are for: "
    "what was done instead starts new processes for the next run as a run ends (spare "
    "workers, `ray_spares.py`), which take the start out of a later set-up and have "
    "hosted nothing; sending every batch's float arrays as one array, found by a "
    "walk over the whole batch on each side, made chain_10000 on Ray slower, not faster "
    "(set-up 7.9 and 8.7 s against 7.3 and 8.1 s, a step 3.1 and 3.2 s against 2.7 and "
    "2.9 s, interleaved on 2026-11-27, under other load): a generic walk in Python costs "
    "as much per object as Ray's own serialization of each array. What was kept packs "
    "only the answers, whose forms are known (a step's kinematics and outputs, a read), "
    "in one pass (`ray_worker.pack_answers`).",
    "",
    "**Ray ahead at 1,000 with spares, and at 10,000 in any case.** Before the "
    "SpringMass FMU declared its variables once per class, an instance took 1.6 ms to "
    "make and chain_1000 set up in 1.9 s in-process: two workers could save half of "
    "that, and with both cores free Ray was ahead even starting its own workers (1.61 s "
    "against 2.29 s, in a run of this script earlier on 2026-11-27). The whole set-up "
    "now costs about 0.5 ms per component, and chain_1000 sets up in-process in about "
    "0.45 s, about what starting one worker process costs: a run whose workers start "
    "as it begins is ahead at chain_1000 only because their start overlaps the reading "
    "and planning of the scene (the table's first Ray row; this script's earlier runs "
    "on 2026-11-27, when every measured Ray run started its workers once the scene was "
    "planned, gave 0.75 s least, Ray faster in 0 of 5), and one that takes spares that "
    "are ready is further ahead; one right after another run is behind. From the "
    "command line, each `dsim run` a new process and a new Ray job, only a running "
    "cluster can hold spares for the next command: there they are detached Ray actors "
    "that end themselves when no command takes them, or when the command that took "
    "them is gone (`ray_pool.py`, docs/distributed.md), and a command that takes them "
    "is ahead of in-process too, back to back also (the next command's Python start, "
    "Ray's connection and the reading of its scene cover the spares' start; the table "
    "above). At chain_10000 the instantiation "
    "outweighs the workers' start: measured on 2026-11-27, each run the first of a "
    "fresh process (as `dsim run` is, with no spare), in turn, two rounds, stop 6 ms: "
    "in-process 5.04 and 4.95 s, Ray 4.24 and 4.25 s, the same bytes; since a worker "
    "answers for its thousands of subsystems with two arrays instead of one per vector "
    "(4.92 to 5.94 s before). A step of chain_10000 on Ray takes about as long as "
    "in-process: 0.85 s mean (0.83 and 0.86 s median in two more rounds) against 0.89 s "
    "(0.87 and 0.90 s) in-process, measured in turn on 2026-11-27, since the workers "
    "send each subsystem's saved state every fourth step and the driver keeps the "
    "batches it sends as bytes (before: 0.97 to 1.04 s); with `--restarts 0`, which "
    "keeps nothing for a fresh worker, 0.81 s (0.78 and 0.81 s): docs/distributed.md. "
    "With more cores per machine, or more machines, the instantiation divides further "
    "while the start of the workers does not grow.",
)


#: what a user running a large scene should know, after the tables
GUIDE = (
    '## Running a large scene',
    '',
    'What to expect, and what helps, with thousands of components (numbers from the tables above and from runs of chain_10000 on these machines on 2026-11-27):',
    '',
    "- **Set-up** costs about half a millisecond and 35 to 45 kB per component besides what its model holds (an ElasticBody's mesh and matrices: docs/elastic_body.md); chain_10000 sets up in about 5 s and runs in about 0.45 GB. On a terminal the progress line counts the FMUs as they are instantiated (`chain_10000 · FMUs instantiated 1,282/10,000`), then says `initialising`; Observer.preparing tells a script the same (docs/api.md).",
    '- **Ctrl-C during the set-up** ends the run within 5 s with its statistics, as during a step; a second Ctrl-C ends it at once (docs/results.md).',
    '- **Look before running**: `dsim validate` and `dsim info` stay linear (the table above); `dsim info` prints counts and one line per distinct FMU, `dsim info --all` every variable (810,000 lines at 10,000 components).',
    '- **Record what you need**: a run records every output it is given and every joint force by default, 20,000 columns at chain_10000; `--outputs` and `--output-interval` choose columns and rows (docs/parameters.md). The statistics JSON holds a table of FMI calls per component, about 1.4 kB each (14 MB at 10,000).',
    '- **In-process or Ray**: on one 2-core machine a step of chain_10000 takes about as long on Ray, which survives a lost worker, as in-process (0.85 s mean against 0.89 s; 0.81 s on Ray with `--restarts 0`, which gives up surviving a lost worker); Ray sets up faster at chain_10000, and at chain_1000 when its workers were started ahead (spare workers: a script that runs several scenes on its own Ray instance, or `dsim run --address` on a running cluster, which keeps them for the next command: below, and docs/distributed.md), but not a `dsim run` that starts Ray itself (below); Ray is above all for running components apart: on other machines, isolated from each other, surviving a lost node.',
    '- **Many scenes in one Python process** (a script, a sweep in-process): each run frees its instances, and what pythonfmu FMUs add to `sys.path` goes with the last of them.',
)


RAY_HEADING = "## Set-up on a local Ray cluster"

#: what the tables rest on, said under them
NOTES = (
    "What keeps these linear: components, ports and joints are found by name through "
    "indices made once (a scan per look-up made validating 10,000 components take a "
    "minute); everything that depends only on an FMU file (its SHA-256, model "
    "description, ports, capability checks) is computed once per file, and a system's "
    "annotations once per system; the gluing incidence is built as one sparse matrix; "
    "Python's cyclic garbage collector is paused while a scene is read, planned and "
    "instantiated (its passes over millions of young objects cost as much as the work), "
    "and the objects the set-up made are frozen out of its passes until the run ends "
    "(`gc.freeze`: at chain_10000 its full passes over a million objects took about "
    "15% of the steps' time), also on the Ray backend's driver; and during a macro "
    "step the collector waits for the step's end (a step of chain_10000 makes tens of "
    "thousands of short-lived objects and few cycles: in-process its passes took 4% of "
    "a step, on Ray, whose driver keeps every call since the last saved state, 0.35 "
    "to 0.4 s of a 1.4 s step). Every instance of one FMU file shares one binding of its library's "
    "functions (`dsim.master.running.fmi.library`: fmpy bound them again for each "
    "instance, 6 ms apiece), and with it the function objects and value-reference "
    "arrays the time loop passes, which are the same for every instance (made per "
    "instance they took about 6 kB each: on 2026-11-27, three rounds in turn, "
    "chain_10000 peaked at 431 MB against 490 MB before, set up in 4.6 to 4.8 s "
    "against 4.8 to 5.0 s, and took 81.5 to 82.5 us of CPU per step and subsystem "
    "against 84.1 to 86.0 us). Two quadratic pieces of set-up found by profiling "
    "chain_10000 on 2026-11-27 and removed: the coupling looked up each subsystem in a "
    "set of the glued ones made again per subsystem (0.8 s at 10,000), and the check "
    "that no output overwrites an input resolved the FMU path of every component "
    "(0.16 s at 1,000: one file, resolved once now).",
    "",
    "The SpringMass instances were most of a large chain's memory and set-up (166 kB "
    "each; 1.86 GB and 25 s of CPU to set up chain_10000): pythonfmu 0.7 runs the FMU's "
    "script again for every instance it makes, to find the model class, and keeps what "
    "that run makes (it never releases the method resolution lists it reads), so a class "
    "defined in the script was made again, with its methods, for each instance; and "
    "pythonfmu registers every variable of every instance as Python objects (95 "
    "variables with a getter and a setter each, about 110 kB). The script now imports "
    "the model class (`fmus/spring_mass/slave.py`), which declares its variables once "
    "for the class (`fmus/fmi_binding.py`, `Variable`: pythonfmu's C side only calls the "
    "slave's get and set methods, which answer from that table). A component then cost "
    "about 33 kB, its FMU instance, dsim's handle of it and the scene's objects for it "
    "together (the resident size over 2,000 components; tracemalloc agrees), and about "
    "6 kB less since its handle shares the library's functions and value references "
    "(above). pythonfmu "
    "also puts the FMU's resources folder at the front of `sys.path` for every instance "
    "and never takes it out (10,000 copies at chain_10000, and more with every run of a "
    "process that runs several scenes): dsim keeps each such entry once while an "
    "instance that added it lives and removes it with the last one "
    "(`dsim.master.running.fmi.python_path`).",
    "",
    "ElasticBody, Linkage2D and FlexibleLink2D now do the same (each script imports its "
    "model class from its subpackage's `slave.py`), with the same model descriptions and "
    "results to the byte. Per instance, made as a run makes them with default parameters "
    "(`python -m benchmarks.fmu_instances`, 2026-11-27: resident size and CPU seconds "
    "from instance 50 to 200 in one process, the old and new builds in turn, least of 3):"
    " ElasticBody 3,340 kB and 7.6 ms before (2,120 variables each), 34 kB and 0.25 ms "
    "now; Linkage2D 87 kB and 0.88 ms before, 15 kB and 0.23 ms now; FlexibleLink2D 99 kB"
    " and 1.11 ms before, 15 kB and 0.23 ms now. Building the model when initialization "
    "ends costs what it did (the default FE beam 320 kB and 3.8 ms), so a default "
    "ElasticBody now takes about a tenth of its memory before (about 350 kB instead of "
    "3,650 kB). After 200 instances a process holds one model class and no pythonfmu variable, "
    "where it held 202 classes and 426,120 (ElasticBody), 8,442 (Linkage2D) or 8,844 "
    "(FlexibleLink2D) variables.",
    "",
    "The time per step per subsystem still grows with the chain, although a step's work "
    "is linear: profiles of steps of chain_1000 and chain_10000 show the same calls per "
    "subsystem (about ten FMI calls, each into the FMU's Python) and no function whose "
    "calls grow; each call takes longer. The FMUs are Python objects spread over memory, "
    "and a step of a large chain visits all of them: the `cores alone` columns step the "
    "SpringMass physics cores one after the other in plain Python, without FMI and "
    "without the master, and grow too from 100 to 10,000 cores; a step of the chain "
    "visits several times more objects per subsystem (pythonfmu's instance, the FMU's "
    "binding and core, fmpy's and dsim's handles of it) and grows more. The machine "
    "is shared (two cores, one 32 MB cache): a step of chain_10000 touches hundreds of "
    "megabytes, and whatever runs beside it empties that cache, so the large chains' "
    "times vary more from run to run than the small ones'.",
    "",
    "Measured on 2026-11-27 (one run each, the run's own statistics, microseconds per "
    "FMI call from chain_100 to chain_10000): fmi2DoStep 10.2 to 13.3 (1.30x, as the "
    "cores alone), fmi2GetReal 3.4 to 6.6, fmi2SetReal 2.4 to 4.3, fmi2SetFMUstate 2.8 "
    "to 7.0, fmi2GetFMUstate 1.5 to 4.0, fmi2FreeFMUstate 0.5 to 2.0, and the master's "
    "Python per step and subsystem 11.7 to 27.4: the small calls, whose work is "
    "reaching their objects, grow most. Sampled instead (py-spy at 250 Hz, each Python "
    "function's own time with the C it calls, no per-call cost added; 2026-11-27), per "
    "step and subsystem from chain_100 to chain_10000: the SpringMass core's Python 26 "
    "to 40 us (its state saved, restored and stepped twice, its outputs), dsim's FMI "
    "adapter with the ctypes calls and pythonfmu's C around each 15 to 28 us, the FMU's "
    "binding 9 to 16 us, the coupling and the backend 3 to 9 us; 54 to 94 us in all: "
    "every layer grows, none alone makes the difference. A step visits every subsystem four times (the "
    "state save, two Newton trials, the output read); one visit less, the save made in "
    "the first trial's visit of each FMU, changed nothing measurable (CPU per step per "
    "subsystem at chain_10000 0.0867 and 0.0849 ms before, 0.0840 and 0.0865 after, "
    "interleaved; at chain_100 0.0433/0.0435 against 0.0444/0.0445) and was not kept: "
    "what grows is the memory each call reaches, not the number of sweeps (the same "
    "again on 2026-11-27: 1 to 2% in two rounds at chain_10000). Nor one output read "
    "less: each trial reading its kinematics and the outputs in one fmi2GetReal (the "
    "last trial's outputs are the step's; the same bits) took 76.9 to 79.6 us per step "
    "and subsystem at chain_10000 against 79.3 to 84.5 us, and 44.8 to 45.7 against "
    "45.8 to 47.2 us at chain_100 (three rounds in turn, 2026-11-27): the ratio stays "
    "where it was, 13 MB more at chain_10000, and frame_split slower (its bodies read "
    "a mixed batch through their full vectors: docs/frame_benchmark.md); not kept. "
    "Nor fewer objects in the core: the SpringMass core's load constants and its step's "
    "three matrices packed into one array each (the same bits) took 78.2 to 79.7 us "
    "per step and subsystem at chain_10000 against 79.4 to 81.2 us, and 45.8 to 47.0 "
    "against 45.5 to 46.0 us at chain_100 (three rounds in turn, 2026-11-27); not kept. "
    "The calls alone, "
    "in a tight loop over the instances of one process with the collector off, least "
    "of 5 loops, from 100 to 10,000 instances: a state save 2.7 to 7.3 us, a restore "
    "2.9 to 7.9 us, a read of the output 2.1 to 7.0 us, of the port kinematics 2.7 to "
    "8.2 us. Reaching "
    "1.2 times chain_100's per step and subsystem would need a subsystem's objects to "
    "fit a few kilobytes of cache each (32 MB over 10,000), far below what a Python FMU "
    "behind pythonfmu and its handles in the master take; the physics cores alone, "
    "stepped in plain Python without FMI or master (the `cores alone` columns), already "
    "grow more than 1.2 times: 1.30 on the machine of the table above and 1.46 on an "
    "AMD EPYC of these machines (2026-11-27, chain_100 against chain_10000, two runs "
    "each in turn), where the whole run grew 1.46 times too (114 to 167 us of CPU per "
    "step and subsystem): there dsim's layers add nothing to the growth. Not the page "
    "tables: with "
    "every object in 2 MB pages (glibc's allocator for all of Python's memory, "
    "`PYTHONMALLOC=malloc GLIBC_TUNABLES=glibc.malloc.hugetlb=1`: 432 of 474 MB resident "
    "in huge pages), chain_10000 took 91 to 95 us per step and subsystem against 86 to "
    "87 us with Python's own allocator in 4 kB pages, and 98 to 103 us with glibc's in "
    "4 kB pages (two rounds in turn on 2026-11-27): Python's allocator, which packs "
    "objects of a size together, keeps a subsystem's objects closer than huge pages "
    "could make up for.",
)


#: the line of docs/benchmarks.md that quotes this page (benchmarks/run_benchmarks.py
#: writes it; this script rewrites it with its page)
QUOTE_START = "**At scale** ("


def _rows(page: str, cells: int) -> dict[str, list[str]]:
    """The rows of the page's tables that have ``cells`` cells, by their first cell."""
    rows = {}
    for line in page.splitlines():
        parts = [part.strip() for part in line.strip().strip("|").split("|")]
        if line.startswith("| ") and len(parts) == cells and parts[0].isdigit():
            rows[parts[0]] = parts
    return rows


def quote(page: str) -> str:
    """The line of docs/benchmarks.md that quotes this page's tables (the text of
    docs/scaling.md): the largest chain's set-up, peak memory and CPU per step and
    subsystem against chain_100's, and the largest scene's validate and info times."""
    written = page.split(" on ", 1)[1].split(" ", 1)[0]  # "Written by ... on DATE (..."
    chains = _rows(page, 13)
    checks = _rows(page, 7)
    largest = max(chains, key=int)
    most = max(checks, key=int)
    chain, check = chains[largest], checks[most]
    return (f"{QUOTE_START}docs/scaling.md, `python -m benchmarks.scaling` on {written}): "
            f"chain_{largest} sets up in {chain[2]} s, peaks at {chain[12]} MB and takes "
            f"{chain[9]} times chain_100's CPU per macro step and subsystem; `dsim "
            f"validate` of {int(most):,} components takes {check[1]} s and `dsim info` "
            f"{check[4]} s.")


def requote(benchmarks: Path, page: str) -> None:
    """Write :func:`quote` of ``page`` over the quote line of the benchmarks page
    ``benchmarks`` (a page without one gets it when run_benchmarks next writes it)."""
    if not benchmarks.is_file():
        return
    lines = benchmarks.read_text().split("\n")
    at = [i for i, text in enumerate(lines) if text.startswith(QUOTE_START)]
    if at:
        lines[at[0]] = quote(page)
        benchmarks.write_text("\n".join(lines))


def chain_folder(n: int, folder: Path) -> Path:
    """A chain of ``n`` subsystems as a scene folder (the FMU in its resources)."""
    from dsim.build_fmus.scenes import CHAIN, chain

    chain(n).write(folder, 0.0, CHAIN["stop"], step=CHAIN["step"], tolerance=1e-13,
                   maxIterations=20, predictor="linear", refreshAfter=10)
    (folder / "resources").mkdir(exist_ok=True)
    shutil.copy(FMU, folder / "resources" / FMU.name)
    return folder


#: steps per window of the CPU time per step (the least window is the table's)
WINDOW = 10


def written_apart(n: int, folder: Path) -> Path:
    """:func:`chain_folder` written by a child process: a child's peak memory counts
    its parent's at the fork (Linux), and this process so stays as small as at its start."""
    subprocess.run([sys.executable, "-c", "import sys; from pathlib import Path; "
                    "from benchmarks.scaling import chain_folder; "
                    "chain_folder(int(sys.argv[1]), Path(sys.argv[2]))", str(n), str(folder)],
                   check=True, cwd=ROOT)
    return folder


def run(folder: Path, steps: int) -> dict:
    """One run of ``steps`` macro steps in a fresh process.

    ``per_step`` is the wall time per step over the whole run (set-up excluded);
    ``first_cpu`` the CPU seconds of the first step, which also measures the interface
    flexibility (the coupling holds none before); ``per_step_cpu`` the least CPU time
    per step over the windows of :data:`WINDOW` consecutive steps after it (the
    machine is shared: the least window is the step's own cost, the others include
    waiting on caches another process emptied), ``mean_cpu`` the mean over them."""
    found = subprocess.run([sys.executable, "-c", _RUN, str(folder), str(steps * 1e-3)],
                           capture_output=True, text=True, check=True)
    result = json.loads(found.stdout.strip().splitlines()[-1])
    marks = result.pop("marks")
    if len(marks) < WINDOW + 2:
        raise ValueError(f"{folder.name}: {len(marks) - 1} steps, fewer than {WINDOW + 1}")
    result["per_step"] = (result["wall"] - result["setup"]) / result["steps"]
    result["first_cpu"] = marks[1] - marks[0]
    result["per_step_cpu"] = min(marks[i + WINDOW] - marks[i]
                                 for i in range(1, len(marks) - WINDOW)) / WINDOW
    result["mean_cpu"] = (marks[-1] - marks[1]) / (len(marks) - 2)
    return result


def least(results: list[dict]) -> dict:
    """Repetitions of one run combined: the least of every time (what the run costs
    with the least interference from other work), the largest peak memory."""
    combined = dict(results[0])
    for key in ("setup", "setup_cpu", "per_step", "first_cpu", "per_step_cpu", "mean_cpu"):
        combined[key] = min(r[key] for r in results)
    combined["peak_mb"] = max(r["peak_mb"] for r in results)
    combined["repetitions"] = len(results)
    return combined


#: n SpringMass cores (the FMU's physics, no FMI, no master) stepped one after the
#: other, as a run steps its FMUs: least CPU microseconds per core and step of 5 sweeps
_CORES = """
import json, sys, time
import numpy as np
from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain
n = int(sys.argv[1])
cores = []
for i in range(n):
    p = ChainParameters()
    p.k_ground[0], p.x0[0] = 1e4, 1e-3 * (i % 7)
    cores.append(SpringMassChain(p))
    cores[-1].initialize(0.0)
sweeps, best, forces = max(2, 20000 // n), float("inf"), np.zeros(2)
for repetition in range(5):
    begun = time.process_time()
    for k in range(sweeps):
        for core in cores:
            core.set_interface_forces(forces)
            core.step(k * 1e-3, 1e-3)
            core.interface_kinematics()
    best = min(best, (time.process_time() - begun) / sweeps / n * 1e6)
print(json.dumps(best))
"""


def cores_alone(n: int) -> float:
    """CPU microseconds per step of one SpringMass core among ``n`` stepped in turn in
    plain Python (no FMI, no master), in a fresh process."""
    found = subprocess.run([sys.executable, "-c", _CORES, str(n)], capture_output=True,
                           text=True, check=True)
    return json.loads(found.stdout.strip().splitlines()[-1])


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
    parser.add_argument("--steps", default="200,50,40,30",
                        help="macro steps of each run (at least %d: the first, then "
                        "windows of %d)" % (WINDOW + 1, WINDOW))
    parser.add_argument("--repeat", type=int, default=3,
                        help="runs of each chain, in turn (the table gives the least times)")
    parser.add_argument("--checks", default="1000,10000,100000",
                        help="components of the validate and info scenes ('': none)")
    parser.add_argument("--ray", type=int, default=1000,
                        help="subsystems of the set-up in-process vs Ray (0: keep the "
                        "page's section)")
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
            commands = cli_setup(args.ray, Path(temp) / "cli", calm=args.calm)
            print(f"dsim run chain_{args.ray}: {commands}", flush=True)
        ray_text = ray_lines(args.ray, result, commands)
    elif Path(args.docs).is_file() and RAY_HEADING in Path(args.docs).read_text():
        # not measured this time: the page's section is kept as it is
        ray_text = [RAY_HEADING + Path(args.docs).read_text().split(RAY_HEADING, 1)[1]]
    if args.only == "ray":
        page = Path(args.docs).read_text()
        kept = page.split(RAY_HEADING)[0].rstrip("\n")
        text = "\n".join([kept, "", *ray_text])
        Path(args.docs).write_text(text)
        return text
    runs, checks, alone = [], [], {}
    with tempfile.TemporaryDirectory(prefix="dsim-scaling-") as temp:
        sizes = list(zip(map(int, args.runs.split(",")), map(int, args.steps.split(","))))
        folders = {n: written_apart(n, Path(temp) / f"chain_{n}") for n, _ in sizes}
        each: dict[int, list] = {n: [] for n, _ in sizes}
        for repetition in range(args.repeat):  # in turn: each size sees the same load
            for n, steps in sizes:
                each[n].append(run(folders[n], steps))
                print(f"chain_{n} ({repetition + 1}/{args.repeat}): {each[n][-1]}", flush=True)
            for n, _ in sizes:
                alone[n] = min(alone.get(n, float("inf")), cores_alone(n))
        runs = [(n, least(each[n])) for n, _ in sizes]
        for folder in folders.values():
            shutil.rmtree(folder)
        for n in (map(int, args.checks.split(",")) if args.checks else ()):
            folder = written_apart(n, Path(temp) / f"chain_{n}")
            checks.append((n, command("validate", folder), command("info", folder)))
            print(f"validate/info chain_{n}: {checks[-1][1:]}", flush=True)
            shutil.rmtree(folder)
    base = next((r["per_step_cpu"] / n for n, r in runs if n == 100), None)
    lines = ["| subsystems | macro steps | set-up: wall (s) | CPU (s) | first step: CPU (ms) "
             "| per macro step: wall (ms) | CPU, mean (ms) | CPU, least window (ms) | CPU per "
             "step per subsystem (ms) | / chain_100's | cores alone: CPU per step per core "
             "(ms) | / 100's | peak memory (MB) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n, r in runs:
        each = r["per_step_cpu"] / n
        lines.append(f"| {n} | {r['steps']} | {r['setup']:.2f} | {r['setup_cpu']:.2f} | "
                     f"{r['first_cpu'] * 1e3:.1f} | {r['per_step'] * 1e3:.1f} | "
                     f"{r['mean_cpu'] * 1e3:.1f} | {r['per_step_cpu'] * 1e3:.1f} | "
                     f"{each * 1e3:.4f} | " + (f"{each / base:.2f}" if base else "-")
                     + f" | {alone[n] * 1e-3:.4f} | "
                     + (f"{alone[n] / alone[100]:.2f}" if 100 in alone else "-")
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
        f"Written by `python -m benchmarks.scaling` on {date.today()} ({machine()}, "
        f"Python {platform.python_version()}, in-process backend). Chains of n SpringMass "
        "FMUs (pythonfmu, one FMU file shared by every component) glued in a line by fixed "
        "joints (`build_fmus/scenes.py`, `chain(n)`), each measured in a fresh process. "
        "Set-up is reading, planning, instantiating and initialising every FMU and the "
        "start forces: wall, the run's `setup_seconds`; CPU, from calling `dsim.simulate` "
        "to the first row. The first step also measures the interface flexibility (the "
        "coupling holds none before). Per macro step: wall, over the whole run; CPU, the "
        "mean over the steps after the first, and the least over every window of "
        f"{WINDOW} consecutive steps after the first, which the columns per subsystem "
        f"use. Each chain runs {args.repeat} times, the sizes in turn, and the table "
        "gives the least of each time and the largest peak memory (the process's maximum "
        "resident size). The machine is shared with other work (two cores): wall seconds "
        "include waiting for a core, CPU seconds are what the run costs.",
        "",
        *lines,
        "",
        "`dsim validate` and `dsim info` (its output written to /dev/null) of chains of "
        "1,000 to 100,000 components, each in a fresh process (about 0.6 s of it is "
        "Python importing dsim):",
        "",
        *check_lines,
        "",
        *NOTES,
        "",
        *GUIDE,
        "",
        *ray_text])
    Path(args.docs).write_text(text)
    requote(Path(args.docs).parent / "benchmarks.md", text)
    return text


if __name__ == "__main__":
    print(main())
