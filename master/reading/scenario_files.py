"""Scenario files as a user writes them for ``dsim run --scenario FILE``: what the file
says, checked for its form only (nothing here knows the scene; the plan resolves each
event against the components' variables: :mod:`dsim.master.planning.scenario`).

Two formats:

- **libcosim's** (``.json``, ``.yml``, ``.yaml``): a top-level object with optional
  ``defaults`` {model, variable, causality, type, action}, a list ``events`` of
  {time, model, variable, causality, type, action, value} (each key but ``time`` and
  ``value`` falling back to ``defaults``) and an optional ``end`` (s).  Actions:
  ``override``, ``bias``, ``reset``.  ``causality`` and ``type`` are informative (libcosim
  reads the variable's own, and so does dsim).
- **ECOS's** (``.xml``): ``<Scenario>`` of ``<action t=".." eps="..">`` elements, each of
  ``<variable id="model::variable">`` with one value element ``<real value=".."/>``,
  ``<integer>``, ``<boolean>`` or ``<string>``; every one an override.  ``eps`` (on the
  action, or on the root for all) widens when an action fires (:class:`ScenarioEvent`).

The file is untrusted input: YAML through ``yaml.safe_load`` only (no Python objects),
XML through a parser that resolves no entity, loads no DTD and reaches no network, and a
size limit before anything is parsed.  A malformed file is one line naming the file and
the line.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from dsim.master.errors import InputError
from dsim.master.reading.small_files import bounded_bytes, parse_untrusted, utf8_text

#: the actions of libcosim's format (ECOS's are all overrides)
ACTIONS = ("override", "bias", "reset")
#: the keys of a libcosim event, and those ``defaults`` may give
EVENT_KEYS = ("time", "model", "variable", "causality", "type", "action", "value")
DEFAULT_KEYS = ("model", "variable", "causality", "type", "action")
#: ECOS's value elements and the FMI type each names
ECOS_TYPES = {"real": "Real", "integer": "Integer", "boolean": "Boolean", "string": "String"}
#: the largest scenario file read (events, not a data set)
MAX_BYTES = 8 * 1024 * 1024
#: the suffixes and the format each is read as
FORMATS = {".json": "libcosim", ".yml": "libcosim", ".yaml": "libcosim", ".xml": "ecos"}


@dataclass(frozen=True)
class ScenarioEvent:
    """One event of a scenario file: at ``time`` (s) the variable ``variable`` of the
    component ``model`` (its path in the scene) gets ``action`` with ``value`` (as the
    file gives it: a number, a boolean or text; None for a reset).  ``rule`` says when
    it fires: ``"libcosim"`` at the first communication point t >= time; ``"ecos"`` at
    the first one with t > time or |t - time| < ``eps`` (ECOS's own test).  ``where``
    names the file and the event for messages."""

    time: float
    model: str
    variable: str
    action: str
    value: object
    where: str
    rule: str = "libcosim"
    eps: float = 0.0
    #: the type the file declares (libcosim's ``type``, ECOS's element), or ''
    declared_type: str = ""


@dataclass(frozen=True)
class Scenario:
    """What a scenario file says: its events in file order, ``end`` (s: every
    modification taken back at the first communication point at or after it; None:
    kept to the stop time), the file and its format (``libcosim`` or ``ecos``)."""

    events: tuple[ScenarioEvent, ...]
    end: float | None
    file: str
    format: str


def read_scenario(path) -> Scenario:
    """The :class:`Scenario` of the file at ``path``, by its suffix (.json, .yml, .yaml:
    libcosim's format; .xml: ECOS's); InputError naming every problem of its form."""
    path = Path(path)
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise InputError(f"{path}: a scenario file is .json, .yml or .yaml (libcosim's "
                         "format) or .xml (ECOS's)")
    data = bounded_bytes(path, MAX_BYTES, "a scenario file")
    if kind == "ecos":
        return _ecos(path, data)
    text = utf8_text(path, data)
    tree = _json(path, text) if path.suffix.lower() == ".json" else _yaml(path, text)
    return _libcosim(path, tree)


# --- libcosim: JSON and YAML ---------------------------------------------------------
def _json(path: Path, text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise InputError(f"{path} line {error.lineno}: malformed JSON: {error.msg} "
                         f"(column {error.colno})") from None


def _yaml(path: Path, text: str):
    import yaml  # only where a YAML scenario is read

    try:
        return yaml.safe_load(text)  # plain data only: never yaml.load
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise InputError(f"{path}{line}: malformed YAML: {problem}") from None


def _time(value, where: str, problems: list, name: str = "time") -> float | None:
    """``value`` as a finite time (s), or None with the problem said."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        problems.append(f"{where}: '{name}' is {value!r}: give a number of seconds")
        return None
    if not math.isfinite(value):
        problems.append(f"{where}: '{name}' is {value!r}: give a finite number of seconds")
        return None
    return float(value)


def _libcosim(path: Path, tree) -> Scenario:
    """The scenario of a parsed libcosim JSON or YAML document."""
    if not isinstance(tree, dict):
        raise InputError(f"{path}: a scenario is an object with 'events' (and optional "
                         f"'defaults' and 'end'), not {type(tree).__name__}")
    problems = []
    unknown = sorted(str(k) for k in tree if k not in ("defaults", "events", "end"))
    if unknown:
        problems.append(f"{path}: unknown key{'s' * (len(unknown) > 1)} "
                        f"{', '.join(unknown)} (a scenario has defaults, events, end)")
    defaults = tree.get("defaults") or {}
    if not isinstance(defaults, dict):
        problems.append(f"{path}: 'defaults' is not an object of "
                        f"{', '.join(DEFAULT_KEYS)}")
        defaults = {}
    for key in defaults:
        if key not in DEFAULT_KEYS:
            problems.append(f"{path}: defaults: unknown key '{key}' (defaults give "
                            f"{', '.join(DEFAULT_KEYS)})")
    events = tree.get("events")
    if not isinstance(events, list):
        raise InputError(problems + [f"{path}: 'events' is missing or not a list"])
    end = None
    if tree.get("end") is not None:
        end = _time(tree["end"], f"{path}", problems, "end")
    parsed = []
    for number, event in enumerate(events, start=1):
        where = f"{path}: event {number}"
        if not isinstance(event, dict):
            problems.append(f"{where}: not an object of {', '.join(EVENT_KEYS)}")
            continue
        found = _libcosim_event(event, defaults, where, problems)
        if found is not None:
            parsed.append(found)
    if problems:
        raise InputError(problems)
    return Scenario(tuple(parsed), end, str(path), "libcosim")


def _libcosim_event(event: dict, defaults: dict, where: str, problems: list):
    """One libcosim event, its keys falling back to ``defaults``, or None (said)."""
    before = len(problems)
    for key in event:
        if key not in EVENT_KEYS:
            problems.append(f"{where}: unknown key '{key}' (an event has "
                            f"{', '.join(EVENT_KEYS)})")
    if "time" not in event:
        problems.append(f"{where}: no 'time'")
        time = None
    else:
        time = _time(event["time"], where, problems)
    given = {}
    for key in ("model", "variable", "action"):
        value = event.get(key, defaults.get(key))
        if value is None:
            problems.append(f"{where}: no '{key}', neither here nor in 'defaults'")
        elif not isinstance(value, str) or not value.strip():
            problems.append(f"{where}: '{key}' is {value!r}: give a name")
        else:
            given[key] = value.strip()
    action = given.get("action")
    if action is not None and action not in ACTIONS:
        problems.append(f"{where}: unknown action '{action}' (the actions are "
                        f"{', '.join(ACTIONS)})")
    value = event.get("value")
    if action in ("override", "bias") and "value" not in event:
        problems.append(f"{where}: action '{action}' needs a 'value'")
    if action == "reset" and "value" in event:
        problems.append(f"{where}: action 'reset' takes no 'value'")
    if isinstance(value, (dict, list)):
        problems.append(f"{where}: 'value' is a {type(value).__name__}: give a number, "
                        "true/false or text")
    declared = event.get("type", defaults.get("type")) or ""
    if len(problems) > before:
        return None
    return ScenarioEvent(time, given["model"], given["variable"], action, value, where,
                         declared_type=str(declared))


# --- ECOS: XML ---------------------------------------------------------------------
def _local(element) -> str:
    """An element's name without its namespace (ECOS writes ``ecos:action``)."""
    return etree.QName(element).localname if isinstance(element.tag, str) else ""


def _eps(element, inherited: float, where: str, problems: list) -> float:
    text = element.get("eps")
    if text is None:
        return inherited
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 0:
        problems.append(f"{where}: eps '{text}' is not a number of seconds at least 0")
        return inherited
    return value


def _ecos(path: Path, data: bytes) -> Scenario:
    """The scenario of an ECOS scenario XML file."""
    try:
        root = parse_untrusted(data, remove_comments=True)
    except etree.XMLSyntaxError as error:
        line = f" line {error.lineno}" if error.lineno else ""
        raise InputError(f"{path}{line}: malformed XML: {error.msg}") from None
    if _local(root) != "Scenario":
        raise InputError(f"{path} line {root.sourceline}: the root element is "
                         f"<{_local(root)}>, not an ECOS <Scenario>")
    problems, events = [], []
    default_eps = _eps(root, 0.0, f"{path} line {root.sourceline}: Scenario", problems)
    for action in root:
        if not isinstance(action.tag, str):
            continue
        where = f"{path} line {action.sourceline}"
        if _local(action) != "action":
            problems.append(f"{where}: <{_local(action)}> where an <action> belongs")
            continue
        try:
            time = float(action.get("t", ""))
        except ValueError:
            time = math.nan
        if not math.isfinite(time):
            problems.append(f"{where}: action: t '{action.get('t')}' is not a number of "
                            "seconds")
            continue
        eps = _eps(action, default_eps, f"{where}: action", problems)
        for variable in action:
            if isinstance(variable.tag, str):
                found = _ecos_variable(variable, time, eps, path, problems)
                if found is not None:
                    events.append(found)
    if problems:
        raise InputError(problems)
    return Scenario(tuple(events), None, str(path), "ecos")


def _ecos_variable(variable, time: float, eps: float, path: Path, problems: list):
    """The override one ``<variable id="model::name">`` element gives, or None (said)."""
    where = f"{path} line {variable.sourceline}"
    if _local(variable) != "variable":
        problems.append(f"{where}: <{_local(variable)}> where a <variable> belongs")
        return None
    identifier = variable.get("id", "")
    model, separator, name = identifier.partition("::")
    if not separator or not model.strip() or not name.strip():
        problems.append(f"{where}: variable id '{identifier}': give MODEL::VARIABLE")
        return None
    values = [child for child in variable if isinstance(child.tag, str)]
    if len(values) != 1 or _local(values[0]) not in ECOS_TYPES:
        problems.append(f"{where}: variable '{identifier}': give one of "
                        f"{', '.join(f'<{k}>' for k in ECOS_TYPES)} with a value")
        return None
    value = values[0].get("value")
    if value is None:
        problems.append(f"{where}: variable '{identifier}': <{_local(values[0])}> has no "
                        "value attribute")
        return None
    return ScenarioEvent(time, model.strip(), name.strip(), "override", value,
                         f"{where}: variable '{identifier}'", rule="ecos", eps=eps,
                         declared_type=ECOS_TYPES[_local(values[0])])
