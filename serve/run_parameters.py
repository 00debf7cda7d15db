"""Model parameters for one run of a stored scene, from the scene page's form or the
JSON API: what the form shows (built from the FMUs' modelDescriptions: name, type,
unit, start, limits), and the server-side check of what it sends.

Form fields are untrusted (docs/security.md): their names and values are only text
handed to dsim's own checks (``dsim run --set``'s, through :func:`dsim.prepare`), which run
in a child process over the stored scene, as an upload's inspection does; the values a
run stores are the ones those checks answer.
"""
from __future__ import annotations

import json

from dsim.serve.forms import FormError
from dsim import SETTINGS
from dsim.serve.uploads import inspect_file, UploadError

#: the prefix of a form field that sets a parameter (``parameter:left.m[1]``)
FIELD = "parameter:"
#: at most this many parameters per run, names and values at most this long: a form
#: is for people, and a field of megabytes is not a value
MOST, LONGEST_NAME, LONGEST_VALUE = 2000, 400, 4000


def _limited(values: dict) -> dict:
    problems = []
    if len(values) > MOST:
        problems.append(f"{len(values)} parameters: at most {MOST} per run")
    for name, value in values.items():
        if not isinstance(name, str) or not name.strip() or len(name) > LONGEST_NAME:
            problems.append(f"parameter name {str(name)[:60]!r}: give COMPONENT.VARIABLE "
                            f"(at most {LONGEST_NAME} characters)")
        elif isinstance(value, (dict, type(None))) or len(json.dumps(value)) > LONGEST_VALUE:
            problems.append(f"parameter '{name}': a value is a number, true/false or text "
                            f"of at most {LONGEST_VALUE} characters")
    if problems:
        raise FormError(problems)
    return values


def form_values(fields: dict) -> dict:
    """name -> text of the form's non-empty ``parameter:NAME`` fields (an empty one
    keeps the scene's value)."""
    values = {}
    for key, value in fields.items():
        if key.startswith(FIELD) and str(value).strip():
            values[key[len(FIELD):]] = str(value).strip()
    return _limited(values)


def checked(store, scene: dict, values: dict, max_unpacked: int) -> dict:
    """``values`` (name -> text or JSON value) as a run of ``scene`` applies them, after
    every check of ``dsim run --set``; FormError listing what is wrong."""
    if not values:
        return {}
    _limited(values)
    try:
        answer = inspect_file("parameters", store.blob_path(scene["sha256"]), max_unpacked,
                              scene["filename"], json.dumps(values))
    except UploadError as error:
        raise FormError(error.problems) from None
    return answer["parameters"]


def _shown(value) -> str:
    """A value as the form shows it: a float to 10 significant digits (14.14, not
    14.139999999999999), anything else as text."""
    return format(value, ".10g") if isinstance(value, float) else str(value)


def form_groups(scene: dict, models: dict) -> list[dict]:
    """The form's rows, one group per component and one per flexible or penalized
    joint: ``{"title", "rows": [{"field", "name", "type", "unit", "value",
    "placeholder", "limits", "choices", "description"}]}``.  A scene stored before
    the description listed what can be set shows its FMUs' parameters."""
    d = scene["description"]
    groups = []
    for component in d["components"]:
        rows = d.get("settable", {}).get(component["path"])
        if rows is None:  # an older description: the parameters of the stored model
            variables = models.get(component.get("model_id"), {}).get("variables", ())
            given = component["parameters"]
            rows = [{**v, "min": None, "max": None, "items": [],
                     "value": given[v["name"]][1] if v["name"] in given else None}
                    for v in variables if v["causality"] == "parameter"
                    and v["variability"] != "constant"]
        shown = []
        for row in rows:
            value = row["start"] if row.get("value") is None else row["value"]
            if isinstance(value, bool):
                value = str(value).lower()
            limits = ""
            if row.get("min") or row.get("max"):
                limits = f"[{row.get('min') or '-inf'}, {row.get('max') or 'inf'}]"
            shown.append({"field": f"{FIELD}{component['path']}.{row['name']}",
                          "name": row["name"], "type": row["type"], "unit": row["unit"] or "",
                          "placeholder": "" if value is None else _shown(value),
                          "limits": limits, "choices": row.get("items") or [],
                          "causality": row["causality"],
                          "description": row.get("description") or ""})
        groups.append({"title": f"component {component['path']}", "rows": shown})
    for joint in d["joints"]:
        rows = [{"field": f"{FIELD}{joint['name']}.{key}", "name": key, "type": "Real",
                 "unit": "", "placeholder": " ".join(_shown(v) for v in joint[key])
                 if isinstance(joint[key], list) else _shown(joint[key]), "limits": ">= 0"
                 if key in ("k0", "c0", "xi", "omega") else "", "choices": [],
                 "causality": "joint law", "description": "one value for every dof, or one "
                 "per dof" if isinstance(joint[key], list) else ""}
                for key in joint.get("settable", ())]
        if rows:
            groups.append({"title": f"joint {joint['name']}", "rows": rows})
    return groups


def scenario_words(given: dict) -> list[str]:
    """The options of a scenario a run or sweep was given (serve/run_scenario.py), as
    the file the worker writes into its folder."""
    words = ["--scenario", f"scenario.{given['format']}"]
    if given.get("events", "point") != "point":
        words += ["--events", given["events"]]
    return words


def command_options(settings: dict) -> str:
    """The ``dsim run`` options of a run's stored settings (its parameters as
    ``--set NAME=VALUE``), quoted for a POSIX shell."""
    import shlex

    words = []
    for key, value in settings.items():
        if key == "parameters" and isinstance(value, dict):
            for name, given in value.items():
                text = " ".join(map(repr, given)) if isinstance(given, list) else (
                    str(given).lower() if isinstance(given, bool) else
                    repr(given) if isinstance(given, float) else str(given))
                words += ["--set", shlex.quote(f"{name}={text}")]
        elif key == "scenario" and isinstance(value, dict):  # written into the run's folder
            words += scenario_words(value)
        else:
            words += [_option(key), shlex.quote(str(value))]
    return " ".join(words)


def _option(keyword: str) -> str:
    """The command-line option of a setting's keyword (``relative_tolerance`` ->
    ``--relative-tolerance``), as dsim's table of settings names it."""
    setting = SETTINGS.get(keyword)
    return setting.option if setting is not None else f"--{keyword.replace('_', '-')}"


def sweep_command(spec: dict, scene: str = "scene.ssp") -> str:
    """The ``dsim sweep`` command that makes the sweep of a stored spec
    (:func:`dsim.serve.forms.sweep_spec`: grid, fixed settings, vary lines, design,
    samples, seed, KPIs, reference), quoted for a POSIX shell: run over the scene's
    .ssp it gives the very same points."""
    import shlex

    words = ["dsim", "sweep", scene]
    for keyword, values in (spec.get("grid") or {}).items():
        words += [_option(keyword), ",".join(str(v) for v in values)]
    for keyword, value in (spec.get("fixed") or {}).items():
        words += [_option(keyword), str(value)]
    for line in spec.get("vary") or ():
        words += ["--vary", line]
    if spec.get("design") and spec["design"] != "grid":
        words += ["--design", spec["design"]]
    for key in ("samples", "seed"):
        if spec.get(key) is not None:
            words += [f"--{key}", str(spec[key])]
    for kpi in spec.get("kpis") or ():
        words += ["--kpi", kpi]
    if spec.get("reference"):
        words += ["--reference", str(spec["reference"])]
    if spec.get("scenario"):  # written into the sweep's folder
        words += scenario_words(spec["scenario"])
    return " ".join(shlex.quote(w) for w in words)


def run_command(run: dict, scene: str = "scene.ssp") -> str:
    """The command line that makes ``run`` (a stored run or sweep) again: ``dsim run``
    with its settings and ``--set`` values, or ``dsim sweep`` with its design."""
    if run.get("kind") == "sweep":
        return sweep_command(run.get("settings") or {}, scene)
    options = command_options(run.get("settings") or {})
    return f"dsim run {scene}" + (f" {options}" if options else "")

