"""``dsim validate``: every check ``dsim run`` makes before it starts, without running.

The SSP 1.0 schemas (fmpy ships them), the files a scene references, each FMU (a
readable archive, FMI 2.0 co-simulation, a library that loads for this platform),
declared connectors against the FMUs' variables (causality, type, unit), parameter
values against FMI's rules, connections (existence, causality, type, units), joints
and ports (known components, ports with every dof the joint needs), capabilities and
settings.  The same code as a run's: a scene that validates starts.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from dsim.master.api import prepare
from dsim.master.errors import InputError


@dataclass
class Validation:
    """What validating a scene found: ``errors`` (it cannot run), ``warnings``, and a
    one-line summary of the scene when it is valid."""

    errors: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    summary: str = ""

    @property
    def ok(self) -> bool:
        return not self.errors


def validate(scene, load_libraries: bool = False, **settings) -> Validation:
    """Check ``scene`` (a path, as :func:`dsim.prepare` takes) with ``settings``.  No
    FMU library is loaded unless ``load_libraries``: validating a file must not run
    its code (a library runs its constructors when loaded); each library is checked
    as bytes (present for this platform, a whole ELF shared object)."""
    try:
        plan = prepare(scene, load_libraries=load_libraries, **settings)
    except InputError as error:
        return Validation(error.problems, error.warnings)
    found = plan.scene
    free = len(found.components) - len(plan.glued)
    summary = (f"{found.file}: valid: {len(found.components)} components ({len(plan.glued)} "
               f"glued, {free} free), {len(found.joints)} joints, {len(found.connections)} "
               f"connections; runs {found.start_time:g} .. {found.stop_time:g} s in steps of "
               f"{found.master.step:g} s (from {found.step_from}) with the {plan.coupling} coupling")
    return Validation([], list(plan.warnings), summary)
