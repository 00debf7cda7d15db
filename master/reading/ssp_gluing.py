"""dsim's SSP annotation (namespace ``urn:dsim:gluing:1``): glue joints and port maps
of a system (docs/annotation.md)."""
from __future__ import annotations

import math

from dsim.master.reading.ssp_values import NS
from dsim.master.scene import DOFS, MEASURES, Joint, PortMap


def floats(text: str | None, n: int, default: float, where: str, problems: list) -> tuple:
    """A space-separated list broadcast to n entries (one value serves all)."""
    if text is None:
        return (default,) * n
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        problems.append(f"{where}: '{text}' is not a number or list of numbers")
        return (default,) * n
    if len(values) == 1:
        values *= n
    if len(values) != n or not all(math.isfinite(v) for v in values):
        problems.append(f"{where}: expected 1 or {n} finite values, got '{text}'")
        return (default,) * n
    return tuple(values)


def _port_ref(text: str | None, where: str, prefix: str, problems: list):
    if not text or "." not in text:
        problems.append(f"{where}: port reference '{text}' is not 'component.port'")
        return ("", "")
    component, port = text.rsplit(".", 1)
    return (prefix + component, port)


def read_joint(element, prefix: str, where: str, problems: list) -> Joint:
    """A ``glue:Joint`` of the system at ``prefix`` (names relative to it)."""
    dofs = tuple((element.get("dofs") or "").split())
    if not dofs or any(d not in DOFS for d in dofs):
        problems.append(f"{where}: dofs '{element.get('dofs')}' must be a list of {DOFS}")
        dofs = dofs or ("x",)
    kind = element.get("kind", "fixed")
    if kind not in ("fixed", "flexible"):
        problems.append(f"{where}: kind '{kind}' must be fixed or flexible")
    measure = element.get("measure", "displacement")
    if measure not in MEASURES:
        problems.append(f"{where}: measure '{measure}' must be one of {MEASURES}")
    n = len(dofs)
    spring = element.find("glue:Spring", NS)
    damper = element.find("glue:Damper", NS)
    values = {}
    for key, node in (("k0", spring), ("k1", spring), ("c0", damper), ("c1", damper)):
        text = node.get(key) if node is not None else None
        values[key] = floats(text, n, 0.0, f"{where}: {key}", problems)
    if kind == "flexible" and spring is None:
        problems.append(f"{where}: a flexible joint needs a glue:Spring")
    xi, omega = 1.0, 0.0
    penalty = element.find("glue:Penalty", NS)
    if measure == "penalized":
        if penalty is None:
            problems.append(f"{where}: measure 'penalized' needs a glue:Penalty")
        else:
            xi = floats(penalty.get("xi"), 1, 1.0, f"{where}: xi", problems)[0]
            omega = floats(penalty.get("omega"), 1, 0.0, f"{where}: omega",
                            problems)[0]
    support = floats(element.get("support"), 1, 1.0, f"{where}: support", problems)[0]
    if not support > 0:
        problems.append(f"{where}: support must be positive")
    return Joint(
        name=prefix + element.get("name", ""),
        a=_port_ref(element.get("a"), where, prefix, problems),
        b=_port_ref(element.get("b"), where, prefix, problems),
        dofs=dofs, kind=kind, measure=measure, xi=xi, omega=omega,
        support=support, location=where, **values)


def read_placement(element, prefix: str, where: str, problems: list) -> tuple[str, str, str]:
    """A ``glue:Placement``: (component path, Ray resource, where) -- the component
    runs on a node of the Ray cluster that has the resource (docs/distributed.md)."""
    resource = (element.get("resource") or "").strip()
    if not resource:
        problems.append(f"{where}: attribute 'resource' missing (a Ray resource: a custom "
                        "one of `ray start --resources`, or node:IP)")
    return prefix + element.get("component", ""), resource, where


def read_port_map(element, prefix: str, where: str, problems: list) -> PortMap:
    """A ``glue:Port`` map of the system at ``prefix``."""
    dofs = tuple((element.get("dofs") or "").split())

    def names(attribute, required=True):
        text = element.get(attribute)
        if text is None:
            if required:
                problems.append(f"{where}: attribute '{attribute}' missing")
            return None
        listed = tuple(text.split())
        if len(listed) != len(dofs):
            problems.append(f"{where}: '{attribute}' names {len(listed)} variables "
                            f"for {len(dofs)} dofs")
        return listed

    return PortMap(
        prefix + element.get("component", ""), element.get("name", ""), dofs,
        names("force"), names("position"), names("velocity", False),
        names("acceleration", False), where)
