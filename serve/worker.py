"""A run (or sweep) of ``dsim serve`` in its own process:
``python -m dsim.serve.worker RUN_FOLDER``.

The folder holds ``job.json`` (what to run, written by the server); the worker
writes there, through dsim's own observers, ``results.csv`` and
``results.stats.json`` (a sweep: ``sweep.csv``, ``sweep.md``, ``sweep.png`` and
one CSV per point), ``live.jsonl`` (samples for the live page, see
:class:`LiveObserver`) and, when it ends however it ends, ``outcome.json``.

SIGTERM or SIGINT end the run after the current step with everything written
(dsim's own signal handling): that is how the server cancels a run.  If the
server dies, the worker notices that its parent is gone and stops the same way,
so a killed server leaves no orphan runs behind.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path

from dsim import (CsvRecorder, Execution, InputError, Observer, prepare, read_scenario,
                  run_sweep, StatisticsWriter)
from dsim.serve.forms import job_sweep

#: seconds between two live samples (the first and last step are always sent)
SAMPLE_SECONDS = 0.05


def _finite(value) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


class LiveObserver(Observer):
    """Appends the run's health and chosen signals to ``live.jsonl``, one JSON line
    per sample, at most every :data:`SAMPLE_SECONDS`: ``start`` (columns, components,
    span), then ``sample`` lines with the step ``i``, simulated time ``t``, wall
    seconds, Newton iterations per step since the last sample (mean and most),
    flexibility (Lambda) refreshes so far, residual, the chosen signals ``v`` and
    the seconds spent inside each FMU so far (non-finite numbers as null)."""

    def __init__(self, path: Path, signals, execution=None):
        self.path = Path(path)
        self.wanted = list(signals)
        self.execution = execution
        self.files = {}
        self._last = 0.0
        self._pending = None
        self._most = self._steps = self._iterations = 0
        self._refreshes = 0

    def _write(self, entry: dict) -> None:
        self._file.write(json.dumps(entry, allow_nan=False) + "\n")
        self._file.flush()

    def started(self, info) -> None:
        self._file = open(self.path, "a")
        self._columns = [c for c in self.wanted if c in info.columns]
        self._index = [info.columns.index(c) for c in self._columns]
        self._start = time.perf_counter()
        names = list(getattr(self.execution.plan, "specs", ()))
        self._write({"type": "start", "columns": self._columns,
                     "units": [(info.units or {}).get(c, "") for c in self._columns],
                     "components": [spec.name for spec in names],
                     "start": info.start_time, "stop": info.stop_time,
                     "planned": info.planned_steps, "coupling": info.coupling})

    def _fmu_seconds(self) -> list[float]:
        backend = self.execution.backend if self.execution else None
        if backend is None:
            return []
        return [round(sum(seconds for _, seconds in counters.values()), 6)
                for counters in backend.counters()]

    def _sample(self, record) -> dict:
        steps = max(self._steps, 1)
        return {"type": "sample", "i": record.index, "t": record.time,
                "wall": round(time.perf_counter() - self._start, 4),
                "it_mean": self._iterations / steps, "it_max": self._most,
                "refreshes": self._refreshes, "res": _finite(record.residual),
                "v": [_finite(record.values[i]) for i in self._index],
                "fmu": self._fmu_seconds()}

    def stepped(self, record) -> None:
        if record.index:
            self._steps += 1
            self._iterations += record.iterations
            self._most = max(self._most, record.iterations)
            self._refreshes += record.refreshed
        now = time.perf_counter()
        if record.index == 0 or now - self._last >= SAMPLE_SECONDS:
            self._write(self._sample(record))
            self._last, self._pending = now, None
            self._most = self._steps = self._iterations = 0
        else:
            self._pending = record

    def finished(self, result) -> None:
        if self._pending is not None:
            self._write(self._sample(self._pending))
        self._write({"type": "end", "status": result.status, "message": result.message})
        self._file.close()

    def aborted(self) -> None:
        self._file.close()


#: set when the server that started this worker is gone
ORPHANED = threading.Event()


def _watch_parent(parent: int) -> None:
    """Stop the run as if cancelled when the server that started it is gone."""
    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            ORPHANED.set()
            os.kill(os.getpid(), signal.SIGTERM)
            return


def _digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def input_hashes(plan, scene_sha: str) -> dict:
    """sha256 of every input of a run: the scene archive, and inside it the SSD,
    parameter files and each component's FMU (names as in the archive)."""
    scene = plan.scene
    base = Path(scene.inputs[0]).parent if scene.inputs else Path(scene.file).parent
    hashes = {"scene.ssp": scene_sha}
    for path in list(scene.inputs) + [c.source for c in scene.components]:
        try:
            name = Path(path).relative_to(base).as_posix()
        except ValueError:
            name = Path(path).name
        hashes.setdefault(name, _digest(path))
    return hashes


def _scenario_file(given: dict, folder: Path) -> Path:
    """The scenario a run or sweep was launched with (serve/run_scenario.py: its text
    and format) written into its folder, a file created, never reused."""
    scenario = folder / f"scenario.{given['format']}"
    with open(scenario, "x", encoding="utf-8") as file:
        file.write(given["text"])
    return scenario


def run_scene(job: dict, folder: Path) -> dict:
    """One run of ``dsim run`` with the job's settings; its outcome."""
    settings = dict(job["settings"])
    given = settings.pop("scenario", None)
    if given:  # the scenario's text, checked when the run was launched, as a file here
        settings.update(scenario=_scenario_file(given, folder),
                        events=given.get("events", "point"))
    plan = prepare(folder / "scene.ssp", **settings)
    (folder / "inputs.json").write_text(json.dumps(input_hashes(plan, job["scene_sha256"])))
    live = LiveObserver(folder / "live.jsonl", job.get("signals", ()))
    execution = Execution(plan, [CsvRecorder(folder / "results.csv"),
                                 StatisticsWriter(folder / "results.stats.json"), live])
    live.execution = execution
    result = execution.run(handle_signals=True)
    return {"status": result.status, "message": result.message,
            "exit_code": result.exit_code, "steps": result.steps, "time": result.time,
            "warnings": list(result.warnings)}


def run_sweep_job(job: dict, folder: Path) -> dict:
    """A ``dsim sweep`` of the scene; its outcome (points as ``point`` lines).  A sweep
    whose points all ran is completed, also when some of them failed: its message says
    how many failed and why (the first reasons); it fails only when no point ran."""
    sweep = job_sweep(job)
    if job.get("scenario"):  # its text, checked at launch, as a file of this folder
        sweep.scenario = read_scenario(_scenario_file(job["scenario"], folder))
        sweep.events = job["scenario"].get("events", "point")
    (folder / "inputs.json").write_text(json.dumps({"scene.ssp": job["scene_sha256"]}))
    with open(folder / "live.jsonl", "a") as live:
        def progress(done, total, point):
            live.write(json.dumps({"type": "point", "done": done, "total": total,
                                   "label": point.label, "status": point.status,
                                   "error": point.error if point.error == point.error
                                   else None, "wall": point.wall_seconds}) + "\n")
            live.flush()
        points, interrupted = run_sweep(folder / "scene.ssp", sweep, folder, progress)
    failed = [p for p in points if p.status not in ("completed", "interrupted")]
    status = ("interrupted" if interrupted else
              "failed" if not points or len(failed) == len(points) else "completed")
    reasons = "; ".join(f"point {p.index}: {p.message or p.status}" for p in failed[:3])
    message = (f"interrupted after {sum(p.finished for p in points)} finished points"
               if interrupted else
               f"{len(failed)} of {len(points)} points failed: {reasons}" if failed else "")
    return {"status": status, "message": message,
            "exit_code": 128 + interrupted if interrupted else int(status == "failed"),
            "steps": len(points), "time": None, "warnings": []}


def main(argv=None) -> int:
    """Run the job of one folder; exit 0 when ``outcome.json`` was written."""
    folder = Path((sys.argv[1:] if argv is None else argv)[0])
    job = json.loads((folder / "job.json").read_text())
    threading.Thread(target=_watch_parent, args=(job["server_pid"],), daemon=True).start()
    link = folder / "scene.ssp"
    if not link.exists():
        link.symlink_to(job["scene"])
    try:
        outcome = (run_sweep_job if job["kind"] == "sweep" else run_scene)(job, folder)
    except InputError as error:
        outcome = {"status": "failed", "message": "bad input: " + "; ".join(error.problems),
                   "exit_code": 2, "steps": 0, "time": None, "warnings": error.warnings}
    except Exception as error:  # reported as the run's failure, never hidden
        traceback.print_exc()
        outcome = {"status": "failed", "message": f"{type(error).__name__}: {error}",
                   "exit_code": 1, "steps": 0, "time": None, "warnings": []}
    if ORPHANED.is_set():
        outcome["message"] = f"the server stopped while it ran: {outcome['message']}"
    partial = folder / ".outcome.json.partial"
    partial.write_text(json.dumps(outcome, default=str))
    os.replace(partial, folder / "outcome.json")
    return 0


if __name__ == "__main__":
    from dsim import end_process

    end_process(main())  # outcome.json is written; the FMU libraries' exit handlers must not run
