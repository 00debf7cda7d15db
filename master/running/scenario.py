"""A scenario's events applied at the communication points of a run (``dsim run
--scenario``; resolved by :mod:`dsim.master.planning.scenario`).

The execution calls :meth:`ScenarioRun.at_point` before the step that starts at a
communication point and :meth:`ScenarioRun.stepped` after it, and only where the run
has a scenario (a run without one takes the step loop as it is).  Each kind of target
is changed where the run already moves its value, through the backend protocol only:

- an input a connection feeds: the run's transfer is a :class:`ModifiedTransfer`, whose
  values (every coupling, the causal kernel, the strong coupling's iterations and the
  algebraic loops compute the connected inputs through them) carry the modification;
- an input no connection feeds, or a tunable parameter: ``Backend.set_values`` at the
  point (before the step saves its state, so a rollback keeps the value);
- an output: the values read after every step are modified in place before they are
  recorded and passed on, so the CSV and the connected inputs see the same value;
- a joint's law coefficient (``j1.k0``): the coupling's joint law is changed at the
  point (:meth:`JointStates.set_law`), so the step that starts there is solved with it
  (the coupling refactors its gluing matrix when the law changes what it holds).

Every change is recorded for the statistics (:attr:`ScenarioRun.applied`): the point's
time, the target, the action, the value before and the value after.
"""
from __future__ import annotations

import numpy as np

from dsim.master.running.connections import Transfer
from dsim.master.running.joints import measure_weights

#: what a modification does to the unmodified value
OVERRIDE, BIAS = "override", "bias"


def _modified(raw: float, mode: str, value: float) -> float:
    """The value a modification makes of ``raw``."""
    return value if mode == OVERRIDE else raw + value


class _Modifications:
    """The modifications in force, shared by a transfer and its restricted copies:
    transfer position -> (mode, value) of the connected inputs modified."""

    CHECKPOINTED = ("inputs",)

    def __init__(self):
        self.inputs: dict[int, tuple[str, float]] = {}


class ModifiedTransfer(Transfer):
    """A :class:`~dsim.master.running.connections.Transfer` whose values carry the
    scenario's modifications of connected inputs; its restricted copies (a coupling's
    glued and free subsystems) share them.  ``positions``: each value's position in
    the run's full transfer (the modifications are keyed by it)."""

    def __init__(self, base: Transfer, modifications: _Modifications, positions=None):
        super().__init__(base.gather, base.factor, base.offset, base.targets, base.tables)
        # every value goes through values() (the causal kernel's np.take shortcut too)
        self.identity = False
        self.modifications = modifications
        self.positions = np.arange(self.size) if positions is None else \
            np.asarray(positions, dtype=int)
        self._local = {int(p): i for i, p in enumerate(self.positions)}

    def raw_values(self, outputs: np.ndarray) -> np.ndarray:
        """The connected inputs' values without the modifications."""
        return Transfer.values(self, outputs)

    def values(self, outputs: np.ndarray) -> np.ndarray:
        values = Transfer.values(self, outputs)
        for position, (mode, value) in self.modifications.inputs.items():
            local = self._local.get(position)
            if local is not None:
                values[local] = _modified(values[local], mode, value)
        return values

    def restricted(self, indices) -> "ModifiedTransfer":
        plain = Transfer.restricted(self, indices)
        chosen = set(indices)
        kept = [p for index, start, stop in self.targets if index in chosen
                for p in self.positions[start:stop]]
        # Transfer.restricted keeps the subsystems in the order of ``indices``' positions
        # only through its targets, which follow self.targets: the same order as kept
        return ModifiedTransfer(plain, self.modifications, kept)


def _shown(kind: str, value):
    """A value as the statistics give it: by the variable's type."""
    if value is None:
        return None
    if kind == "Integer":
        return int(round(float(value)))
    if kind == "Boolean":
        return bool(value)
    if kind == "String":
        return str(value)
    return float(value)


class ScenarioRun:
    """The state of one run's scenario (a
    :class:`~dsim.master.planning.scenario.ScenarioPlan`): what is modified now, and
    every change applied so far (:attr:`applied`)."""

    #: what a checkpoint keeps (:mod:`dsim.master.running.checkpointing`)
    CHECKPOINTED = ("_modifications", "_outputs", "_raw", "_current", "_active", "applied")

    def __init__(self, scenario, transfer: Transfer):
        self.plan = scenario
        self.targets = scenario.targets
        self._modifications = _Modifications()
        #: the run's transfer, carrying the modifications of connected inputs
        self.transfer = ModifiedTransfer(transfer, self._modifications)
        self._by_point: dict[int, list] = {}
        for event in scenario.events:
            self._by_point.setdefault(event.point, []).append(event)
        #: outputs modified: flat position -> (mode, value), and their values as read
        self._outputs: dict[int, tuple[str, float]] = {}
        self._raw: dict[int, float] = {}
        #: set targets: target index -> current value (their unmodified value first)
        self._current = {i: t.base for i, t in enumerate(self.targets)
                         if t.kind in ("set", "joint")}
        #: joint targets changed at this point, to set on the coupling's joints
        self._laws_to_set: list[int] = []
        #: targets modified now (index -> True), in the order they were first modified
        self._active: dict[int, bool] = {}
        #: every change applied: {"time", "event_time", "target", "action", "old", "new"}
        self.applied: list[dict] = []

    # --- what the execution calls -------------------------------------------------------
    def at_point(self, point: int, time: float, outputs: np.ndarray, backend,
                 coupling=None) -> None:
        """Apply the events that take effect at communication point ``point`` (its time
        ``time``, s; ``outputs``: the run's flat outputs there), then, at the
        scenario's end, take every modification back.  ``coupling``: the run's, whose
        joint laws a ``joint`` target changes."""
        self._apply_events([e for e in self._by_point.get(point, ()) if not e.inside],
                           time, outputs, backend, coupling,
                           end=point == self.plan.end_point)

    def cuts(self, point: int) -> list[float]:
        """The times (s) inside the step from ``point`` at which events take effect
        (``--events exact``), in order: where the step is cut."""
        return sorted({e.at for e in self._by_point.get(point, ()) if e.inside})

    def at_time(self, point: int, time: float, outputs: np.ndarray, backend,
                coupling=None) -> None:
        """Apply the events inside the step from ``point`` that take effect at ``time``
        (one of :meth:`cuts`), between the two parts of the cut step."""
        self._apply_events([e for e in self._by_point.get(point, ())
                            if e.inside and e.at == time], time, outputs, backend, coupling)

    def _apply_events(self, events, time: float, outputs: np.ndarray, backend, coupling,
                      end: bool = False) -> None:
        """Apply ``events`` at ``time`` (s) and, with ``end``, take every modification
        back; then set what they set through the backend and the coupling's joints."""
        settings = []
        for event in events:
            self._apply(event.target, event.action, event.value, time, event.time,
                        outputs, settings)
        if end:
            for index in list(self._active):
                self._apply(index, "reset", None, time, self.plan.end, outputs, settings,
                            label="end")
        if settings:
            backend.set_values(_batched(settings))
        self._set_laws(coupling)

    def restored(self, coupling) -> None:
        """After a checkpoint's state is restored (``--resume``): the joint laws the
        scenario had changed by then, set again (a checkpoint keeps the joints' state;
        their laws come from the plan)."""
        self._laws_to_set = [i for i, t in enumerate(self.targets) if t.kind == "joint"]
        self._set_laws(coupling)

    def _set_laws(self, coupling) -> None:
        """Give the coupling's joints the current value of every joint target changed
        since the last call (each dof its own, found by its row's label ``j.f_x``)."""
        for index in self._laws_to_set:
            target = self.targets[index]
            dofs, xi, omega = self.plan.joints[target.path]
            rows = [r for r, name in enumerate(coupling.layout.joint_of) if name == target.path]
            if target.variable in ("xi", "omega"):
                current = {"xi": xi, "omega": omega}
                for other, kept in enumerate(self.targets):
                    if kept.kind == "joint" and kept.path == target.path \
                            and kept.variable in current:
                        current[kept.variable] = self._current[other]
                coupling.joints.set_law(rows, "weights", measure_weights(
                    "penalized", current["xi"], current["omega"]))
            else:
                value = self._current[index]
                coupling.joints.set_law(rows, target.variable, [
                    value[dofs.index(coupling.layout.labels[r].rsplit(".f_", 1)[1])]
                    for r in rows])
        self._laws_to_set = []

    def stepped(self, outputs: np.ndarray) -> None:
        """Modify the outputs read after a step (in place), keeping their values as read."""
        for position, (mode, value) in self._outputs.items():
            self._raw[position] = outputs[position]
            outputs[position] = _modified(outputs[position], mode, value)

    # --- one change -----------------------------------------------------------------------
    def _apply_law(self, index: int, target, action: str, value, time: float, event_time,
                   label) -> None:
        """A joint law coefficient overridden (every dof), offset from its unmodified
        value (each dof's), or reset; set on the coupling's joints after the point's
        events (:meth:`_set_laws`)."""
        old, base = self._current[index], target.base
        if action == "reset":
            new = base
            self._active.pop(index, None)
        else:
            offset = action != OVERRIDE
            new = (float(value) + (base if offset else 0.0)) if np.isscalar(base) else \
                tuple(float(value) + (b if offset else 0.0) for b in base)
            self._active[index] = True
        self._current[index] = new
        if index not in self._laws_to_set:
            self._laws_to_set.append(index)
        self.applied.append({"time": time, "event_time": event_time, "target": target.name,
                             "kind": target.kind, "action": label or action,
                             "old": _law_shown(old), "new": _law_shown(new)})

    def _apply(self, index: int, action: str, value, time: float, event_time, outputs,
               settings: list, label: str | None = None) -> None:
        target = self.targets[index]
        if target.kind == "input":
            old = self.transfer.values(outputs)[target.position]
            raw = self.transfer.raw_values(outputs)[target.position]
            table = self._modifications.inputs
        elif target.kind == "output":
            old = outputs[target.position]
            raw = self._raw[target.position] if target.position in self._outputs else old
            table = self._outputs
        elif target.kind == "joint":
            self._apply_law(index, target, action, value, time, event_time, label)
            return
        else:  # set through the backend
            old, raw, table = self._current[index], target.base, None
        if action == "reset":
            new = raw
            if table is not None:
                table.pop(target.position, None)
            if target.kind == "output":
                self._raw.pop(target.position, None)
            self._active.pop(index, None)
        else:
            number = float(value) if target.type in ("Real", "Integer") else value
            new = number if action == OVERRIDE else raw + number
            if table is not None:
                table[target.position] = (action, number)
            self._active[index] = True
        if target.kind == "set":
            self._current[index] = new
            settings.append((target.component, target.variable, _shown(target.type, new)))
        self.applied.append({"time": time, "event_time": event_time, "target": target.name,
                             "kind": target.kind, "action": label or action,
                             "old": _shown(target.type, old),
                             "new": _shown(target.type, new)})


def _law_shown(value):
    """A joint law coefficient as the statistics give it: one number, or one per dof
    where the dofs differ."""
    values = [float(v) for v in np.atleast_1d(value)]
    return values[0] if len(set(values)) == 1 else values


def _batched(settings) -> list[tuple[int, tuple, tuple]]:
    """(subsystem, name, value) triples as one (subsystem, names, values) entry per
    subsystem, in order (a later value of one name wins)."""
    batches: dict[int, dict] = {}
    for component, name, value in settings:
        batches.setdefault(component, {})[name] = value
    return [(component, tuple(values), tuple(values.values()))
            for component, values in batches.items()]
