"""A run's checkpoints (docs/checkpoints.md): when they are taken, what they hold of
dsim's own state, and how a run goes on from one.

Each stateful object of a run names what a checkpoint keeps of it in a class
attribute ``CHECKPOINTED`` (the coupling, its joints, its algebraic loops' solver,
the error-controlled step, the coupling error watch, a scenario's state); what is
derived from those (the gluing matrix's factor) is made again when the run resumes
(``Coupling.resumed``), and every FMU's state comes from the backend as bytes
(``Backend.save_states``).  What this module keeps is plain data: the checkpoint
files hold no pickle (:mod:`~dsim.master.recording.state_codec`).
"""
from __future__ import annotations

import math
from collections import defaultdict

from dsim.master.errors import InputError, SimulationError
from dsim.master.recording.output_files import OutputError

#: the counts a run started from a checkpoint (``--from``) begins again from zero
COUNTS = ("refreshes", "factorizations", "cuts", "regularized", "least_squares_steps",
          "roundoff_steps", "solves", "corrections", "jacobians", "damped", "evaluations")


def _names(obj) -> list[str]:
    names = []
    for klass in reversed(type(obj).__mro__):
        names += [n for n in klass.__dict__.get("CHECKPOINTED", ()) if n not in names]
    return names


def kept(obj):
    """What a checkpoint keeps of ``obj``: its ``CHECKPOINTED`` attributes (those that
    are such objects in turn, alone or in a list, kept the same way), plain data."""
    if obj is None:
        return None
    if isinstance(obj, list):
        return [kept(item) for item in obj]
    if not _names(obj):
        return obj
    return {name: kept(getattr(obj, name, None)) for name in _names(obj)}


def restore(obj, saved):
    """Set ``obj``'s ``CHECKPOINTED`` attributes to ``saved`` (what :func:`kept` gave),
    objects among them restored in place (a shared object stays shared); the object."""
    if isinstance(obj, list) and isinstance(saved, list) and len(obj) == len(saved) \
            and all(_names(item) for item in obj):
        for item, state in zip(obj, saved):
            restore(item, state)
        return obj
    if obj is None or not _names(obj):
        if isinstance(obj, defaultdict) and isinstance(saved, dict):
            return defaultdict(obj.default_factory, saved)
        return saved
    if not isinstance(saved, dict):
        raise InputError(f"the checkpoint holds no state of a {type(obj).__name__}")
    for name in _names(obj):
        if name in saved:
            setattr(obj, name, restore(getattr(obj, name, None), saved[name]))
    return obj


def run_state(execution) -> dict:
    """dsim's state of ``execution`` at its current communication point, and every
    subsystem's (the FMUs' serialized states; their calls not counted)."""
    return {"execution": {"index": execution.index, "time": execution.time,
                          "iterations": dict(execution._iterations),
                          "warnings": list(execution.warnings),
                          "said_notes": list(execution._said_notes),
                          "texts": list(execution._texts)},
            "coupling": kept(execution.coupling),
            "controller": kept(execution.controller),
            "watch": kept(execution._watch),
            "scenario": kept(execution.scenario),
            "subsystems": execution.backend.save_states(),
            "counters": execution.backend.counters()}


def structure(execution) -> dict:
    """What a run's checkpoint must agree with to be resumed by another run: the
    components in order, the recorded columns and the joint dofs."""
    return {"components": list(execution.backend.names),
            "columns": list(execution._columns),
            "joint_dofs": len(execution.coupling.forces)}


def _check_structure(found: dict, now: dict, where: str) -> None:
    for key, what in (("components", "components"), ("columns", "recorded columns"),
                      ("joint_dofs", "joint dofs")):
        if found.get(key) != now[key]:
            raise InputError(f"{where}: the scene's {what} differ from the checkpoint's "
                             "(another scene, or the same one changed since)")


def resume_run(execution, checkpoint, fresh: bool = False, changed=()) -> None:
    """Bring ``execution`` (initialized, at its start) to ``checkpoint``'s state: every
    subsystem's, the coupling's and the rest of dsim's.  ``fresh``: a new run starting
    there (``--from``): its counts, warnings, scenario and coupling error watch are its
    own, from zero, and ``changed`` (subsystem index, names, values) is set on top of
    the saved states (tunable parameters given anew)."""
    where = f"checkpoint {checkpoint.folder}"
    state = checkpoint.state
    _check_structure(checkpoint.manifest.get("structure") or {}, structure(execution), where)
    try:
        counters = state["counters"] if not fresh else [{} for _ in state["counters"]]
        execution.backend.load_states(state["subsystems"], counters)
        restore(execution.coupling, state["coupling"])
        execution.coupling.resumed()
        if fresh:
            for counted in (execution.coupling, execution.coupling.loop_solver):
                for name in COUNTS:
                    if counted is not None and isinstance(getattr(counted, name, None), int):
                        setattr(counted, name, 0)
        if changed:
            execution.backend.set_values(list(changed))
            execution.coupling.read_outputs()  # what the new values give now
        if execution.controller is not None and state["controller"] is not None:
            saved = state["controller"]
            if fresh:  # the step it had reached, not what it counted
                saved = {k: saved[k] for k in ("_level", "_previous") if k in saved}
            restore(execution.controller, saved)
        if fresh:
            return
        if execution._watch is not None and state["watch"] is not None:
            restore(execution._watch, state["watch"])
        if execution.scenario is not None and state["scenario"] is not None:
            restore(execution.scenario, state["scenario"])
            execution.scenario.restored(execution.coupling)
        own = state["execution"]
        execution.index, execution.time = own["index"], own["time"]
        execution._iterations = defaultdict(int, own["iterations"])
        execution.warnings[:] = own["warnings"]
        execution._said_notes[:] = own["said_notes"]
        execution._texts = list(own["texts"])
    except (KeyError, TypeError, ValueError, IndexError, NotImplementedError,
            SimulationError) as error:
        raise InputError(f"{where}: cannot go on from it: {error}") from None


class Checkpointer:
    """Writes a run's checkpoints into ``folder`` (a
    :class:`~dsim.master.recording.checkpoints.CheckpointFolder`) at the first recorded
    communication point at or after every ``every`` seconds of simulated time, and
    when the run is interrupted; ``manifest``: what each checkpoint's manifest says
    of the run besides the step (its request, the digests of its files); ``results``:
    the run's CSV recorder, whose length and digest each checkpoint records."""

    def __init__(self, folder, every: float, manifest: dict, results=None):
        self.folder = folder
        self.every = every
        self.manifest = manifest
        self.results = results
        self._next = None
        self._origin = 0.0
        self._said = False

    def open(self, start: float) -> None:
        """Lock the folder; the first checkpoint is due ``every`` after ``start`` (s)."""
        self.folder.open()
        self._origin = start
        self._next = self._after(start)

    def _after(self, time: float) -> float:
        """The first multiple of ``every`` past ``time`` (s) on the run's grid."""
        count = math.floor((time - self._origin) / self.every + 1e-9) + 1
        return self._origin + count * self.every

    def resumed_at(self, time: float, origin: float) -> None:
        """A resumed run: checkpoints on the grid of the run that wrote them."""
        self._origin = origin
        self._next = self._after(time)

    def due(self, time: float) -> bool:
        """Whether a checkpoint is due at the recorded point ``time`` (s)."""
        return self._next is not None and time >= self._next - 1e-9 * max(1.0, abs(time))

    def take(self, execution) -> None:
        """Write the checkpoint of ``execution`` now; one that cannot be written is a
        warning (once), and the run goes on."""
        self._next = self._after(execution.time)
        manifest = dict(self.manifest)
        manifest.update(step=execution.index, time=execution.time,
                        structure=structure(execution))
        try:
            if self.results is not None:
                manifest["results"] = {"csv": self.results.position()}
            self.folder.write(execution.index, manifest, run_state(execution))
        except (OutputError, OSError) as error:
            if not self._said:
                self._said = True
                execution.warn(f"checkpoint at t = {execution.time:g} s not written: {error}"
                               " (the run goes on; later checkpoints are tried)")

    def statistics(self) -> dict:
        """What the statistics say of this run's checkpoints."""
        folder = self.folder
        last = folder.written[-1] if folder.written else None
        return {"folder": str(folder.folder), "every": self.every, "keep": folder.keep,
                "written": len(folder.written),
                "last": None if last is None else {"step": last[0], "name": last[1].name},
                "seconds": folder.seconds, "bytes": folder.bytes}

    def close(self) -> None:
        self.folder.close()
