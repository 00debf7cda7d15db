"""The integrator settings of a Model Exchange component, as an SSD gives them.

OMSimulator writes them on the component or on a system around it:
``<ssc:Annotation type="org.openmodelica"><oms:Annotations><oms:SimulationInformation>
<oms:VariableStepSolver description="cvode" relativeTolerance=".." absoluteTolerance=".."
maximumStepSize=".."/>``; dsim reads the same attributes from its own
``<ssc:Annotation type="org.dsim.solver"><glue:Solver method="cvode" rtol=".." atol=".."
maxStep=".."/>``.  The innermost element that says one wins.  The result is a tuple
of (name, value) pairs in :mod:`dsim.master.running.fmi.integrator`'s names.
"""
from __future__ import annotations

#: OMSimulator's attribute -> dsim's setting
OMS_NAMES = {"relativeTolerance": "rtol", "absoluteTolerance": "atol",
             "maximumStepSize": "max_step"}
DSIM_NAMES = {"method": "method", "rtol": "rtol", "atol": "atol", "maxStep": "max_step"}
#: OMSimulator's solver names -> dsim's methods ("euler" is a fixed-step explicit
#: Euler there; dsim has none, so the nearest explicit method integrates instead)
OMS_METHODS = {"cvode": "cvode", "euler": "RK23"}


def _local(tag) -> str:
    return tag.split("}")[-1] if isinstance(tag, str) else ""


def _own_solver(element) -> tuple[tuple | None, str | None]:
    """The solver settings annotated on ``element`` itself (not its children), and the
    OMSimulator solver name that is not dsim's (None: no such name)."""
    annotations = [child for child in element if _local(child.tag) == "Annotations"]
    for annotations_element in annotations:
        for found in annotations_element.iter():
            name = _local(found.tag)
            if name == "VariableStepSolver":
                pairs = [(OMS_NAMES[k], v) for k, v in found.attrib.items() if k in OMS_NAMES]
                method = found.get("description", "cvode")
                return ((("method", OMS_METHODS.get(method, "cvode")),) + tuple(pairs),
                        None if method in OMS_METHODS else method)
            if name == "Solver" and found.getparent() is not None and \
                    found.getparent().get("type") == "org.dsim.solver":
                return tuple((DSIM_NAMES[k], v) for k, v in found.attrib.items()
                             if k in DSIM_NAMES), None
    return None, None


def solver_of(element, warnings: list, where: str, cache: dict | None = None) -> tuple:
    """The settings for the component ``element``: its own annotation, else that of
    the nearest system around it; () when none says any.  ``cache`` (element -> what
    it annotates), kept by the caller for one document: a system's annotations (its
    joints among them) are read once, not once per component inside it."""
    cache = {} if cache is None else cache
    current = element
    while current is not None:
        # only a component or a system carries one (an Elements list is not looked
        # into: it may hold tens of thousands of components)
        if _local(current.tag) in ("Component", "System"):
            if current not in cache:
                cache[current] = _own_solver(current)
            found, unknown = cache[current]
            if found is not None:
                if unknown is not None:
                    warnings.append(f"{where}: solver '{unknown}' of the OMSimulator "
                                    "annotation is not dsim's: cvode integrates instead")
                return found
        current = current.getparent()
    return ()
