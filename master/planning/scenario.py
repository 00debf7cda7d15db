"""A scenario file's events resolved against a checked plan (``dsim run --scenario``):
which variable of which subsystem each event changes, how the run reaches it, the
value converted by the variable's type, and the communication point at which it takes
effect.  Bad input (an unknown component or variable, a variable no master may change
during a run, a value of another type, an event at or after the stop time) is one
line each of one :class:`~dsim.master.errors.InputError`, before anything runs.

When an event takes effect (``point``, an index of the run's communication points
``start + n * step``; with ``--step auto``, of its output points, every
``output_interval``): libcosim's events at the first point ``t >= time`` (a point
within a millionth of a step of the time counts: ``n * step`` is rounded); ECOS's
actions at the first point with ``t > time`` or ``|t - time| < eps`` (ECOS's own test).
A change made at point n acts on the step that starts there: an input or parameter is
written before that step, an output is modified from the values read after it (so the
row of point n + 1 is the first to show it, as libcosim's observer sees it).  With
``--events exact`` an event inside a step takes effect at its own time: the step is cut
there (``PlannedEvent.inside``; the execution takes it in parts).

How each target is reached (:class:`Target`'s ``kind``):

- ``"input"``: an input (or tunable parameter) a connection feeds every step: the
  value the connection delivers is replaced (override) or offset (bias) where the
  run's transfer computes it (``position`` in its flat values);
- ``"set"``: an input no connection feeds, or a tunable parameter: set through the
  backend when the event takes effect (FMI lets a master set both between steps);
  its unmodified value (``base``) is the value the run started it with (the scene's
  binding or ``--set``, else the FMU's declared start);
- ``"output"``: a numeric output the run reads after every step (``position`` in the
  flat outputs): what connected inputs receive and the CSV records is modified;
- ``"joint"``: a joint's law coefficient (``j1.k0``; ``path`` is the joint's name, the
  ``model`` of the event): the coupling's joint law is changed between steps (every
  dof of the joint; ``base``: its value per dof, or one number for the penalized
  measure's ``xi`` and ``omega``).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from dsim.master.errors import InputError
from dsim.master.planning.names import closest
from dsim.master.planning.parameters import (JOINT_SCALAR, KEPT_TYPE, NON_NEGATIVE,
                                             convert, joint_coefficients)
from dsim.master.planning.plan import takes_any_step
from dsim.master.reading.fmi_description import describe
from dsim.master.reading.scenario_files import Scenario, read_scenario
from dsim.master.running.timeline import step_count

#: how close to an event's time (in steps) a communication point counts as at it:
#: ``start + n * step`` carries round-off (3 * 0.1 = 0.30000000000000004)
ROUNDING = 1e-6
#: the types whose values a bias can add to
ADDABLE = ("Real", "Integer")
#: when events take effect (``--events``): at communication points, or at their times
EVENT_MODES = ("point", "exact")


@dataclass(frozen=True)
class Target:
    """A variable that events change: ``path`` (the component) and ``variable``, the
    index of its subsystem in the plan's specs, its FMI type as dsim keeps it
    (Real, Integer, Boolean, String), how the run reaches it (``kind``: input, set or
    output; module docstring), where it is (the transfer's or the flat outputs'
    ``position``; -1 for a set one) and, for a set one, its unmodified value."""

    component: int
    path: str
    variable: str
    type: str
    kind: str
    causality: str
    position: int = -1
    base: object = None

    @property
    def name(self) -> str:
        return f"{self.path}.{self.variable}"


@dataclass(frozen=True)
class PlannedEvent:
    """One event as the run applies it: at communication point ``point`` (index; its
    time ``at``, s) the target ``target`` (an index into the plan's targets) gets
    ``action`` with ``value`` (converted; None for a reset); ``time``: the time the
    file gives (s); ``where``: the file and event; ``inside``: at ``at`` within the
    step from ``point`` (``--events exact``)."""

    point: int
    at: float
    time: float
    target: int
    action: str
    value: object
    where: str
    #: ``--events exact``: the event falls inside the step that starts at ``point``,
    #: which is cut so that a step ends at ``at`` (= ``time``), where it takes effect
    inside: bool = False


@dataclass(frozen=True)
class ScenarioPlan:
    """A scenario resolved against a plan: its targets, its events in the order they
    take effect (point, then the file's order), and where every modification is taken
    back (``end_point``: the first point at or after ``end`` at which no event is
    still to come, as libcosim does; None: kept to the stop time)."""

    targets: tuple[Target, ...]
    events: tuple[PlannedEvent, ...]
    end: float | None
    end_point: int | None
    end_at: float | None
    file: str
    format: str
    #: joint name -> (its dofs, xi, omega) of every joint a target changes the law of
    joints: dict = None

    def lines(self) -> list[str]:
        """What ``dsim info --scenario`` says: one line per event (when it takes effect,
        the target, the action), then the end."""
        lines = [f"scenario {self.file} ({self.format}'s format): {len(self.events)} "
                 f"event{'s' * (len(self.events) != 1)}"]
        for event in self.events:
            target = self.targets[event.target]
            what = "reset" if event.action == "reset" else f"{event.action} {event.value!r}"
            how = "joint law" if target.kind == "joint" else f"{target.type} {target.kind}" + (
                f", {target.causality}" if target.kind == "set" else "")
            where = (f"the step from point {event.point} cut there" if event.inside
                     else f"point {event.point}")
            lines.append(f"  t = {event.time:g} s -> at t = {event.at:.9g} s ({where}): "
                         f"{target.name} ({how}): {what}")
        if self.end is not None:
            lines.append(f"  end t = {self.end:g} s: every modification taken back" + (
                f" at t = {self.end_at:.9g} s (point {self.end_point})"
                if self.end_point is not None else " (after the stop time: never)"))
        return lines


def _when(event, start: float, step: float, planned: int, exact: bool):
    """(point, time, inside) at which ``event`` takes effect: the communication point by
    its rule (:func:`_point`) and that point's time; with ``exact``, an event inside a
    step (not within ``ROUNDING`` of a point) at its own time, in the step that starts
    at the point before it."""
    if exact:
        n = math.floor((event.time - start) / step)
        near = abs(event.time - (start + n * step)) <= ROUNDING * step
        far = abs(event.time - (start + (n + 1) * step)) <= ROUNDING * step
        if not (near or far) and 0 <= n < planned:
            return n, float(event.time), True
    point = _point(event, start, step, planned)
    return point, start + point * step, False


def _check_exact(plan) -> None:
    """``--events exact`` cuts steps at event times: refused in one line where the step
    is chosen by error control (it lands on the output points; use a finer output
    interval), or where an FMU takes no communication step of another size."""
    if plan.scene.master.adaptive:
        raise InputError("--events exact cuts fixed macro steps at the events' times: with "
                         "--step auto the steps land on the output points, where the "
                         "events take effect (a finer --output-interval brings them closer)")
    fixed = [spec.name for spec in plan.specs
             if spec.table is None and not takes_any_step(spec.path, spec.interface)]
    if fixed:
        raise InputError(
            "--events exact cuts steps at the events' times, and "
            + ", ".join(f"'{name}'" for name in fixed[:5])
            + (f" and {len(fixed) - 5} more" if len(fixed) > 5 else "")
            + " take" + "s" * (len(fixed) == 1) + " no communication step of another "
            "size (canHandleVariableCommunicationStepSize is false): events take effect "
            "at the communication points (--events point)")


def _point(event, start: float, step: float, planned: int) -> int:
    """The first communication point (index, up to ``planned``: the stop time) at which
    ``event`` takes effect by its rule."""
    if event.rule == "ecos":
        # the points that pass ECOS's test are those past time - eps (past time without
        # eps): scan from just before the first, as the run computes each point's time
        n = max(0, math.floor((event.time - event.eps - start) / step) - 1)
        while n < planned:
            t = start + n * step
            if t > event.time or abs(t - event.time) < event.eps:
                return n
            n += 1
        return planned
    n = max(0, math.ceil((event.time - start) / step - ROUNDING))
    return min(n, planned)


def _strict_value(variable, value, ecos: bool):
    """``value`` as the variable's type takes it, or raise ValueError.  A libcosim file
    gives typed values (JSON, YAML): text for a number, a fraction for an Integer, or
    a number for a Boolean is refused; ECOS's are attribute text, read by the type."""
    kind = KEPT_TYPE.get(variable.type)
    if not ecos:
        if kind == "Real" and (isinstance(value, bool) or not isinstance(value, numbers.Real)):
            raise ValueError
        if kind == "Integer" and (isinstance(value, bool) or not isinstance(
                value, numbers.Real) or not float(value).is_integer()):
            raise ValueError
        if kind == "Boolean" and not isinstance(value, bool):
            raise ValueError
        if kind == "String" and not isinstance(value, str):
            raise ValueError
    elif kind == "Boolean" and isinstance(value, str):
        value = {"true": True, "1": True, "false": False, "0": False}.get(
            value.strip().lower(), value)
    converted, problem = convert(variable, value)
    if problem:
        raise ValueError
    return converted


def _base(component, variable):
    """The value a run starts a set variable with: the scene's binding (or --set), else
    the FMU's declared start, else zero of its type."""
    bound = component.parameters.get(variable.name)
    if bound is not None:
        return bound[1]
    zero = {"Real": 0.0, "Integer": 0, "Boolean": False, "String": ""}[KEPT_TYPE[variable.type]]
    if variable.start in (None, ""):
        return zero
    converted, problem = convert(variable, variable.start)
    return zero if problem else converted


def _target(plan, index: int, variable, where: str, problems: list) -> Target | None:
    """How the run reaches ``variable`` of subsystem ``index``, or None (said why)."""
    spec = plan.specs[index]
    component = plan.scene.component(spec.name)
    name = f"{spec.name}.{variable.name}"
    kind = KEPT_TYPE.get(variable.type)
    if kind is None:
        problems.append(f"{where}: '{name}' is of type {variable.type}, which a scenario "
                        "cannot change")
        return None
    causality, variability = variable.causality, variable.variability or ""
    if variability == "constant":
        problems.append(f"{where}: '{name}' is a constant: FMI lets no master change it")
        return None
    if causality == "parameter" and variability != "tunable":
        problems.append(f"{where}: '{name}' is a {variability or 'fixed'} parameter: FMI "
                        "lets a master change it only before the run starts (--set, "
                        "--set-file), not at an event")
        return None
    if causality in ("input", "parameter"):
        forces = {dof.force for dof in spec.port_dofs}
        if causality == "input" and variable.type == "Real" and \
                variable.valueReference in forces:
            problems.append(f"{where}: '{name}' is a glued port's force: the joint sets it "
                            "every step")
            return None
        if variable.name in spec.writes:
            if kind not in ADDABLE + ("Boolean",):
                problems.append(f"{where}: '{name}' is a {kind} input a connection feeds: "
                                "a scenario changes connected numbers only")
                return None
            position = _transfer_position(plan, index, spec.writes.index(variable.name))
            return Target(index, spec.name, variable.name, kind, "input", causality, position)
        if variable.name in spec.text_writes:
            problems.append(f"{where}: '{name}' is a String input a connection feeds: a "
                            "scenario changes connected numbers only")
            return None
        return Target(index, spec.name, variable.name, kind, "set", causality,
                      base=_base(component, variable))
    if causality == "output":
        if kind == "String" or variable.name not in spec.reads:
            why = ("a String output" if kind == "String" else
                   "an output the run does not read (not recorded, connected or declared; "
                   "a port's kinematics go to its joint as the FMU computes them)")
            problems.append(f"{where}: '{name}' is {why}: a scenario modifies the numeric "
                            "outputs the run reads after every step")
            return None
        if plan.step_control is not None:
            problems.append(f"{where}: '{name}' is an output: with --step auto the run "
                            "takes steps between the output points that pass the FMUs' own "
                            "outputs on, so a scenario changes only inputs and tunable "
                            "parameters there (give a fixed --step to modify an output)")
            return None
        if plan.coupling == "strong":
            problems.append(f"{where}: '{name}' is an output, and the strong coupling "
                            "iterates connections on the FMUs' own outputs within a step: "
                            "a scenario modifies outputs under the other couplings")
            return None
        offset = sum(len(s.reads) for s in plan.specs[:index])
        return Target(index, spec.name, variable.name, kind, "output", causality,
                      offset + spec.reads.index(variable.name))
    problems.append(f"{where}: '{name}' is a {causality} variable: a scenario changes "
                    "inputs, tunable parameters and outputs")
    return None


def _transfer_position(plan, index: int, place: int) -> int:
    """Where the ``place``-th written input of subsystem ``index`` is in the transfer's
    flat values."""
    for subsystem, start, _ in plan.transfer.targets:
        if subsystem == index:
            return start + place
    raise KeyError(index)  # a written input has its place in the transfer


def _targetable(description) -> list[str]:
    """Names a scenario could change in an FMU (for the 'closest' names)."""
    return [v.name for v in description.modelVariables
            if v.causality in ("input", "output", "parameter") and v.variability != "constant"]


def resolve_scenario(plan, scenario, events: str = "point") -> ScenarioPlan:
    """``scenario`` (a :class:`~dsim.master.reading.scenario_files.Scenario`, or the
    path of its file) resolved against ``plan`` (a checked
    :class:`~dsim.master.planning.plan.Plan`); InputError listing every problem.
    ``events``: ``point`` (each event at the first communication point at or after its
    time, as libcosim) or ``exact`` (the step an event falls inside is cut at its time,
    where every FMU takes steps of any size)."""
    if events not in EVENT_MODES:
        raise InputError(f"events '{events}' is not one of: {', '.join(EVENT_MODES)}")
    if not isinstance(scenario, Scenario):
        scenario = read_scenario(scenario)
    exact = events == "exact"
    if exact:
        _check_exact(plan)
    scene, step = plan.scene, plan.scene.master.step
    problems = []
    planned = step_count(scene.start_time, scene.stop_time, step)
    index_of = {spec.name: i for i, spec in enumerate(plan.specs)}
    joints = {joint.name: joint for joint in scene.joints}
    targets: dict[tuple[str, str], int] = {}
    found: list[Target] = []
    events = []
    ecos = scenario.format == "ecos"
    for order, event in enumerate(scenario.events):
        where = event.where
        if event.time >= scene.stop_time - ROUNDING * step:
            problems.append(f"{where}: t = {event.time:g} s is at or after the stop time "
                            f"{scene.stop_time:g} s: no step follows it")
            continue
        if scenario.end is not None and event.time > scenario.end:
            problems.append(f"{where}: t = {event.time:g} s is after the scenario's end "
                            f"{scenario.end:g} s, which takes every modification back")
            continue
        index = index_of.get(event.model)
        if index is None and event.model in joints:
            key = (event.model, event.variable)
            joint = joints[event.model]

            def make():
                return _joint_target(joint, event.variable, where, problems)

            def value_of(target):
                return _joint_value(target, event.action, event.value, ecos, where, problems)
        else:
            if index is None:
                problems.append(f"{where}: the scene has no component '{event.model}'"
                                + closest(event.model, {**index_of, **joints}))
                continue
            spec = plan.specs[index]
            description = scene.descriptions.get(scene.component(spec.name).source) or \
                describe(spec.path)
            variable = description.by_name.get(event.variable)
            if variable is None:
                problems.append(f"{where}: component '{event.model}' has no variable "
                                f"'{event.variable}'" + closest(event.variable,
                                                                 _targetable(description)))
                continue
            key = (spec.name, variable.name)

            def make():
                return _target(plan, index, variable, where, problems)

            def value_of(target):
                return _variable_value(target, variable, event, ecos, where, problems)
        if key not in targets:
            target = make()
            if target is None:
                continue
            targets[key] = len(found)
            found.append(target)
        target = found[targets[key]]
        if not _declared_matches(event, target, where, problems):
            continue
        value = None
        if event.action != "reset":
            value = value_of(target)
            if value is _REFUSED:
                continue
        point, at, inside = _when(event, scene.start_time, step, planned, exact)
        if _after_the_stop(event, point, planned, scene, where, problems):
            continue
        events.append((point, order, PlannedEvent(
            point, at, event.time, targets[key], event.action, value, where, inside)))
    if problems:
        raise InputError(problems)
    ordered = tuple(e for _, _, e in sorted(events, key=lambda e: (e[0], e[2].at, e[1])))
    end_point = None
    if scenario.end is not None:
        # libcosim takes everything back at the first point at or after the end at
        # which no event is still to come: after the last event's point, if later
        end_point = max(0, math.ceil((scenario.end - scene.start_time) / step - ROUNDING))
        end_point = max([end_point] + [e.point + 1 for e in ordered])
        if end_point >= planned:
            end_point = None
    laws = {t.path: (tuple(joints[t.path].dofs), float(joints[t.path].xi),
                     float(joints[t.path].omega)) for t in found if t.kind == "joint"}
    return ScenarioPlan(tuple(found), ordered, scenario.end, end_point,
                        None if end_point is None else scene.start_time + end_point * step,
                        scenario.file, scenario.format, laws)


#: what a value check returns for a value it refused (and said why)
_REFUSED = object()


def _variable_value(target: Target, variable, event, ecos: bool, where: str,
                    problems: list):
    """An event's value for an FMU variable, converted by its type, or ``_REFUSED``
    (said why): a value of another type, or a bias of what cannot be added to."""
    try:
        value = _strict_value(variable, event.value, ecos)
    except (TypeError, ValueError, OverflowError):
        problems.append(f"{where}: '{target.name}' is {target.type}: {event.value!r} is not "
                        + {"Real": "a number", "Integer": "an integer",
                           "Boolean": "true or false", "String": "text"}[target.type])
        return _REFUSED
    if event.action == "bias" and target.type not in ADDABLE:
        problems.append(f"{where}: '{target.name}' is {target.type}: a bias adds to a "
                        "number (Real or Integer)")
        return _REFUSED
    return value


def _after_the_stop(event, point: int, planned: int, scene, where: str,
                    problems: list) -> bool:
    """Whether ``event`` takes effect at the stop time (said why): no step follows it."""
    if point < planned:
        return False
    problems.append(f"{where}: t = {event.time:g} s takes effect at the stop time "
                    f"{scene.stop_time:g} s (the first communication point at or after "
                    "it): no step follows it")
    return True


def _joint_target(joint, name: str, where: str, problems: list) -> Target | None:
    """A law coefficient of ``joint`` as a target (kind ``joint``), or None (said why):
    its unmodified value (``base``) is the run's (the scene's, or ``--set``): one per
    dof for the flexible law's coefficients, one number for the penalized measure's."""
    settable = joint_coefficients(joint)
    if name not in settable:
        what = (f"a {joint.kind} joint on the {joint.measure} measure")
        problems.append(f"{where}: joint '{joint.name}' is {what}: it has no law "
                        f"coefficient '{name}'" + (
                            f" (a scenario can change {', '.join(settable)})" if settable
                            else " (a fixed joint on this measure has none to change)"))
        return None
    if name in JOINT_SCALAR:
        base = float(getattr(joint, name))
    else:
        given = getattr(joint, name)
        base = tuple(float(v) for v in given) if given else (0.0,) * len(joint.dofs)
    return Target(-1, joint.name, name, "Real", "joint", "law", base=base)


def _joint_value(target: Target, action: str, value, ecos: bool, where: str,
                 problems: list):
    """An event's number for a joint law coefficient, or ``_REFUSED`` (said why):
    finite, and where the coefficient is physical only when not negative
    (NON_NEGATIVE), the value it makes of every dof's not negative."""
    try:
        if isinstance(value, bool) or not (ecos or isinstance(value, numbers.Real)):
            raise ValueError
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        problems.append(f"{where}: '{target.name}' is a joint law coefficient (Real): "
                        f"{value!r} is not a number")
        return _REFUSED
    if not math.isfinite(number):
        problems.append(f"{where}: '{target.name}': {value!r} is not a finite number")
        return _REFUSED
    if target.variable in NON_NEGATIVE:
        lowest = number + (min(np.atleast_1d(target.base)) if action == "bias" else 0.0)
        if lowest < 0.0:
            problems.append(f"{where}: '{target.name}' would be {lowest:g}: a "
                            f"{target.variable} below zero is not physical")
            return _REFUSED
    return number


def _declared_matches(event, target: Target, where: str, problems: list) -> bool:
    """Whether the type the file declares (libcosim's ``type``, ECOS's element) is the
    variable's (a file that says ``real`` for an Integer is a slip to say, not guess)."""
    declared = (event.declared_type or "").strip()
    if not declared:
        return True
    if declared.lower() != target.type.lower():
        problems.append(f"{where}: '{target.name}' is {target.type}, the file says "
                        f"{declared}")
        return False
    return True
