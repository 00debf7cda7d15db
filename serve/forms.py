"""What the web forms send, read into dsim's terms: run settings (checked by
dsim's own rules, :func:`dsim.resolve`), sweep grids (:func:`dsim.check`), scenes to
assemble and parameter edits.  Each reader returns the value or raises :class:`FormError`
listing every problem."""
from __future__ import annotations

import math

from dsim.serve.assemble import ComponentSpec, SceneSpec, typed_value
from dsim.serve.store import Store
from dsim import (DESIGNS, SETTINGS, check, InputError, MasterSettings, parse_vary, resolve,
                  Sweep, sweep_of)


class FormError(Exception):
    """What is wrong with a form, one line per problem."""

    def __init__(self, problems):
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


def run_settings(fields: dict) -> dict:
    """``dsim run``'s settings from form fields named as its keywords; an empty field
    keeps the scene's value."""
    # the scene a run reads is the one stored, described by its own SystemStructure.ssd
    settings = {k: str(fields[k]).strip() for k in SETTINGS if k != "ssd"
                and str(fields.get(k) or "").strip()}
    try:
        resolve(MasterSettings(), settings)
    except InputError as error:
        raise FormError(error.problems) from None
    return settings


def _list(text: str) -> list[str]:
    return [v for v in text.replace(",", " ").split() if v]


def _lines(text: str) -> list[str]:
    return [line.strip() for line in text.splitlines() if line.strip()
            and not line.strip().startswith("#")]


def sweep_spec(fields: dict, reference: str | None) -> dict:
    """A sweep's grid (``step``, ``tolerance``, ``coupling``, ``predictor``: lists
    separated by commas or spaces), its design of experiments (``vary``: one
    ``NAME=SPEC`` of ``dsim sweep --vary`` per line, settings or model parameters;
    ``design``, ``samples``, ``seed``), its KPIs (``kpis``: one ``--kpi`` per line) and
    fixed settings (``stop``; ``backend``: ray runs the points side by side), checked
    as ``dsim sweep`` checks a sweep file."""
    grid = {name: _list(str(fields.get(name) or "")) for name in
            ("step", "tolerance", "coupling", "predictor")}
    grid = {name: values for name, values in grid.items() if values}
    fixed = {"stop": str(fields["stop"]).strip()} if str(fields.get("stop") or "").strip() \
        else {}
    if str(fields.get("backend") or "") == "ray":
        fixed["backend"] = "ray"
    design = str(fields.get("design") or "grid").strip()
    problems, numbers = [], {}
    for name in ("samples", "seed"):
        text = str(fields.get(name) or "").strip()
        if text:
            try:
                numbers[name] = int(text)
            except ValueError:
                problems.append(f"{name} '{text}' is not a whole number")
    if design not in DESIGNS:
        problems.append(f"design '{design}' is not one of {', '.join(DESIGNS)}")
    vary_lines = _lines(str(fields.get("vary") or ""))
    vary = []
    for line in vary_lines:
        try:
            vary.append(parse_vary(line, design != "grid"))
        except InputError as error:
            problems += error.problems
    kpis = _lines(str(fields.get("kpis") or ""))
    seed = numbers.get("seed", 0 if design != "grid" else None)
    sweep = Sweep(grid=grid, fixed=fixed, vary=vary, design=design,
                  samples=numbers.get("samples"), seed=seed, kpis=kpis)
    if not problems:
        try:
            check(sweep)
        except InputError as error:
            problems += error.problems
    if problems:
        raise FormError(problems)
    return {"grid": grid, "fixed": fixed, "reference": reference, "vary": vary_lines,
            "design": design, "samples": numbers.get("samples"), "seed": seed,
            "kpis": kpis}


def job_sweep(spec: dict):
    """The :class:`~dsim.Sweep` of a stored sweep spec (:func:`sweep_spec`):
    a sweep file's object whose fixed settings are stored as ``fixed``."""
    data = {key: value for key, value in spec.items() if key != "fixed"}
    return sweep_of({**data, "settings": spec.get("fixed", {})})


def _parameters(text: str, variables: dict, where: str, problems: list) -> list:
    """(name, type, SSV text) of ``name = value`` lines, checked against the FMU."""
    values = []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.strip().startswith("#"):
            continue
        name, equals, value = line.partition("=")
        name = name.strip()
        variable = variables.get(name)
        if not equals:
            problems.append(f"{where}, parameter line {number}: write 'name = value'")
        elif variable is None:
            problems.append(f"{where}: the FMU has no variable '{name}'")
        elif variable["causality"] not in ("parameter", "input"):
            problems.append(f"{where}: '{name}' is a {variable['causality']} of the FMU: "
                            "only parameters and inputs take values")
        else:
            try:
                values.append((name, variable["type"], typed_value(variable["type"], value)))
            except ValueError as error:
                problems.append(f"{where}: parameter '{name}' ({variable['type']}): {error}")
    return values


def _joint(fields: dict, k: int, problems: list) -> dict | None:
    def value(name):
        values = fields.get(f"joint_{name}", [])
        return str(values[k]).strip() if k < len(values) else ""

    name, a, b = value("name"), value("a"), value("b")
    if not (name or a or b):
        return None
    where = f"joint {k + 1}" + (f" '{name}'" if name else "")
    for label, text in (("name", name), ("a", a), ("b", b)):
        if not text:
            problems.append(f"{where}: give its {label}")
    joint = {"name": name, "a": a, "b": b, "dofs": value("dofs") or "x",
             "kind": value("kind") or "fixed", "measure": value("measure") or "displacement"}
    for key in ("k0", "k1", "c0", "c1", "xi", "omega"):
        text = value(key)
        if text:
            try:
                numbers = [float(v) for v in text.split()]
                if not all(math.isfinite(x) for x in numbers):
                    raise ValueError
                joint[key] = " ".join(repr(x) for x in numbers)
            except ValueError:
                problems.append(f"{where}: {key} '{text}' is not a number")
    if joint["kind"] == "flexible" and "k0" not in joint:
        problems.append(f"{where}: a flexible joint needs its stiffness k0")
    if joint["measure"] == "penalized" and "omega" not in joint:
        problems.append(f"{where}: the penalized measure needs omega (and xi, default 1)")
    return joint


#: the variable attributes of a port map, and whether each is required
PORT_VARIABLES = {"force": ("input", True), "position": ("output", True),
                  "velocity": ("output", False), "acceleration": ("output", False)}


def _port(fields: dict, k: int, variables_of: dict, problems: list) -> dict | None:
    """A glue:Port map from row ``k`` of the form: a component's variables (one per
    dof) named as a port's force, position, velocity and acceleration."""
    def value(name):
        values = fields.get(f"port_{name}", [])
        return " ".join(str(values[k]).split()) if k < len(values) else ""

    port = {"component": value("component"), "name": value("name"),
            "dofs": value("dofs") or "x", **{key: value(key) for key in PORT_VARIABLES}}
    if not any(port[key] for key in ("component", "name", "force", "position")):
        return None
    where = f"port {k + 1}" + (f" '{port['component']}.{port['name']}'"
                               if port["component"] else "")
    variables = variables_of.get(port["component"])
    if variables is None:
        problems.append(f"{where}: '{port['component']}' is not a component of the scene")
        return port
    if not port["name"] or "." in port["name"]:
        problems.append(f"{where}: give the port a name without dots")
    dofs = port["dofs"].split()
    for key, (causality, required) in PORT_VARIABLES.items():
        names = port[key].split()
        if not names:
            if required:
                problems.append(f"{where}: give its {key} variable(s), one per dof")
            continue
        if len(names) != len(dofs):
            problems.append(f"{where}: {key} names {len(names)} variables for "
                            f"{len(dofs)} dofs ({' '.join(dofs)})")
        for name in names:
            variable = variables.get(name)
            if variable is None or variable["causality"] != causality:
                problems.append(f"{where}: {key} '{name}' is not an {causality} of the FMU")
    return port


def scene_spec(fields: dict, store: Store) -> tuple[SceneSpec, dict]:
    """The scene the assembly form describes, and the stored FMU file of each model
    it uses (sha256 -> path).  ``fields`` maps each form field to its list of values
    (one per row)."""
    problems = []
    name = str((fields.get("name") or [""])[0]).strip()
    if not name:
        problems.append("give the scene a name")
    spec = SceneSpec(name, str((fields.get("description") or [""])[0]).strip())
    files, seen, variables_of = {}, set(), {}
    names = fields.get("component_name", [])
    for k, component in enumerate(names):
        component = str(component).strip()
        model_text = fields.get("component_model", [""] * len(names))[k]
        if not component and not model_text:
            continue
        where = f"component {k + 1}" + (f" '{component}'" if component else "")
        if not component or "." in component:
            problems.append(f"{where}: give it a name without dots")
            continue
        if component in seen:
            problems.append(f"{where}: the name is used twice")
        seen.add(component)
        model = store.one("SELECT * FROM models WHERE id = ?",
                          int(model_text)) if str(model_text).isdigit() else None
        if model is None:
            problems.append(f"{where}: choose one of the stored FMUs")
            continue
        variables = {v["name"]: v for v in model["description"]["variables"]}
        variables_of[component] = variables
        text = fields.get("component_parameters", [""] * len(names))[k]
        parameters = _parameters(str(text), variables, where, problems)
        outputs = []
        for output in _list(str(fields.get("component_record", [""] * len(names))[k])):
            variable = variables.get(output)
            if variable is None or variable["causality"] != "output":
                problems.append(f"{where}: '{output}' is not an output of the FMU")
            else:
                outputs.append((output, variable["type"]))
        spec.components.append(ComponentSpec(component, model["sha256"], parameters, outputs))
        files[model["sha256"]] = store.blob_path(model["sha256"])
    if not spec.components and not problems:
        problems.append("add at least one component")
    starts, ends = fields.get("connection_start", []), fields.get("connection_end", [])
    for k, (start, end) in enumerate(zip(starts, ends)):
        start, end = str(start).strip(), str(end).strip()
        if not start and not end:
            continue
        if "." not in start or "." not in end:
            problems.append(f"connection {k + 1}: write 'component.output' and "
                            "'component.input'")
            continue
        spec.connections.append((tuple(start.split(".", 1)), tuple(end.split(".", 1))))
    for k in range(len(fields.get("joint_name", []))):
        joint = _joint(fields, k, problems)
        if joint:
            spec.joints.append(joint)
    for k in range(len(fields.get("port_component", []))):
        port = _port(fields, k, variables_of, problems)
        if port:
            spec.ports.append(port)
    experiment = {key: str((fields.get(key) or [""])[0]).strip()
                  for key in ("start", "stop", "step", "tolerance", "max_iterations")}
    for key in ("start", "stop"):
        try:
            setattr(spec, key, float(experiment[key] or (0.0 if key == "start" else 1.0)))
        except ValueError:
            problems.append(f"experiment: {key} time '{experiment[key]}' is not a number")
    try:
        spec.master = {k: v for k, v in run_settings(
            {k: experiment[k] for k in ("step", "tolerance", "max_iterations")}).items()}
    except FormError as error:
        problems += error.problems
    if problems:
        raise FormError(problems)
    return spec, files


def _text(value) -> str:
    """A stored value as the form shows it (SSV text: full precision, true/false)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def _numbers(values) -> str:
    return " ".join(repr(float(v)) for v in values) if any(values) else ""


def scene_form(scene: dict) -> dict:
    """The assembly form's fields for a stored scene (``scene``: its row, with the
    description :func:`dsim.serve.inspect.describe_scene` made), named "<name>_edited";
    FormError when the form cannot hold it (nested systems, files of the scene)."""
    d = scene["description"]
    problems = []
    nested = [c["path"] for c in d["components"] if "." in c["path"]]
    if nested:
        problems.append(f"scene '{d['name']}' has nested systems ({', '.join(nested[:3])}"
                        f"{' ...' if len(nested) > 3 else ''}): the form makes flat scenes only")
    if d.get("scene_files"):
        problems.append(f"scene '{d['name']}' has parameters naming its own files "
                        f"({', '.join(d['scene_files'][:3])}): the form cannot carry them")
    if problems:
        raise FormError(problems)
    master = d["master"]
    fields = {"name": [f"{d['name']}_edited"], "description": [d.get("description", "")],
              "start": [_text(d["start_time"])], "stop": [_text(d["stop_time"])],
              "step": [_text(master["step"])], "tolerance": [_text(master["tolerance"])],
              "max_iterations": [_text(master["max_iterations"])]}
    for c in d["components"]:
        fields.setdefault("component_name", []).append(c["path"])
        fields.setdefault("component_model", []).append(str(c.get("model_id", "")))
        fields.setdefault("component_parameters", []).append("\n".join(
            f"{name} = {_text(value)}" for name, (_, value) in c["parameters"].items()))
        fields.setdefault("component_record", []).append(" ".join(c["outputs"]))
    for j in d["joints"]:
        row = {"name": j["name"], "a": j["a"], "b": j["b"], "dofs": " ".join(j["dofs"]),
               "kind": j["kind"], "measure": j["measure"],
               **{key: _numbers(j[key]) for key in ("k0", "c0", "k1", "c1")},
               "xi": _text(j.get("xi", 1.0)) if j["measure"] == "penalized" else "",
               "omega": _text(j.get("omega", 0.0)) if j["measure"] == "penalized" else ""}
        for key, value in row.items():
            fields.setdefault(f"joint_{key}", []).append(value)
    for p in d.get("port_maps", []):
        row = {"component": p["component"], "name": p["name"], "dofs": " ".join(p["dofs"]),
               **{key: " ".join(p[key]) for key in PORT_VARIABLES}}
        for key, value in row.items():
            fields.setdefault(f"port_{key}", []).append(value)
    for c in d["connections"]:
        fields.setdefault("connection_start", []).append(c["start"])
        fields.setdefault("connection_end", []).append(c["end"])
    return fields


def parameter_edits(fields: dict, rows: list[dict]) -> list:
    """(root-relative name, type, SSV text) of every parameter whose field differs
    from the value shown (``rows``: the editable parameters in page order)."""
    problems, values = [], []
    for k, row in enumerate(rows):
        text = str(fields.get(f"value_{k}", row["value"])).strip()
        if text == str(row["value"]):
            continue
        try:
            values.append((f"{row['component']}.{row['name']}", row["type"],
                           typed_value(row["type"], text)))
        except ValueError as error:
            problems.append(f"{row['component']}.{row['name']} ({row['type']}): {error}")
    if problems:
        raise FormError(problems)
    if not values:
        raise FormError(["no value changed: edit at least one parameter"])
    return values
