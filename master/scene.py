"""The plain, immutable description of a glued system that the SSP reader
(:mod:`dsim.master.reading.ssp`) produces and the rest of the master consumes."""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

DOFS = ("x", "y", "z", "rx", "ry", "rz")
MEASURES = ("displacement", "velocity", "acceleration", "penalized")
PREDICTORS = ("none", "constant", "linear", "quadratic")


@dataclass(frozen=True)
class Joint:
    """A glue joint between port ``a`` and port ``b`` (component path, port).

    Port b receives +F, port a receives -F.  Flexible joints follow the
    Kelvin-Voigt law (k0 + k1 |q|) q + (c0 + c1 |qd|) qd = -F per dof (eq. 5.3/5.36,
    with the seed's sign of eq. 5.32); fixed joints have q = 0.
    """

    name: str
    a: tuple[str, str]
    b: tuple[str, str]
    dofs: tuple[str, ...]
    kind: str = "fixed"
    measure: str = "displacement"
    k0: tuple[float, ...] = ()
    k1: tuple[float, ...] = ()
    c0: tuple[float, ...] = ()
    c1: tuple[float, ...] = ()
    xi: float = 1.0
    omega: float = 0.0
    support: float = 1.0
    location: str = ""


@dataclass(frozen=True)
class PortMap:
    """Maps a third-party FMU's variables onto a port (one name per dof)."""

    component: str
    name: str
    dofs: tuple[str, ...]
    force: tuple[str, ...]
    position: tuple[str, ...]
    velocity: tuple[str, ...] | None
    acceleration: tuple[str, ...] | None
    location: str = ""


@dataclass(frozen=True)
class Connector:
    """A declared connector of a component or system: SSP kind (input, output,
    parameter, calculatedParameter, inout), value type and unit (None: not given)."""

    name: str
    kind: str
    type: str | None = None
    unit: str | None = None


@dataclass(frozen=True)
class Component:
    """An FMU instance: dotted path, FMU file, parameter values (name -> (type, value),
    after every binding that reaches it, with ``origins`` saying where each came from),
    declared connectors, and the scene files its String parameters name."""

    path: str
    source: Path
    parameters: dict = field(default_factory=dict)
    connectors: tuple[Connector, ...] = ()
    location: str = ""
    origins: dict = field(default_factory=dict)
    #: String parameters naming a file of the scene (``resources/...``) -> that file
    files: dict = field(default_factory=dict)
    #: the interface the SSD asks for (``implementation``: "", CoSimulation,
    #: ModelExchange or any)
    implementation: str = ""
    #: the Model Exchange integrator's settings the SSD gives, as (name, value) pairs
    #: (:mod:`dsim.master.reading.ssp_solver`)
    solver: tuple = ()
    #: the communication steps per macro step its ``glue:Substeps`` annotation gives,
    #: as (the text of ``count``, where it stands), or () without one (checked, and
    #: overridden by ``--substeps``, in :mod:`dsim.master.planning.substeps`)
    substeps: tuple = ()


@dataclass(frozen=True)
class Transformation:
    """A value transformation of SSP: ``linear`` (value * factor + offset) or a mapping
    table (``boolean``, ``integer``, ``enumeration``: source -> target)."""

    kind: str
    factor: float = 1.0
    offset: float = 0.0
    table: tuple[tuple, ...] = ()

    def apply(self, value):
        """The transformed value (KeyError: a mapping has no entry for it)."""
        if self.kind == "linear":
            return value * self.factor + self.offset
        return dict(self.table)[value]


@dataclass(frozen=True)
class Unit:
    """An SSP unit: exponents of kg m s A K mol cd rad, and value_SI = factor * value + offset."""

    name: str
    exponents: tuple[int, ...]
    factor: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Connection:
    """A causal connection between two component variables, across system levels:
    output ``start`` feeds input ``end`` through ``transformations`` (in order); the
    connector units at both ends (None where none is declared)."""

    start: tuple[str, str]
    end: tuple[str, str]
    transformations: tuple[Transformation, ...] = ()
    units: tuple[str | None, str | None] = (None, None)
    location: str = ""
    #: False when a connection on the way says suppressUnitConversion
    convert_units: bool = True


@dataclass(frozen=True)
class MasterSettings:
    """The master's settings (annotation ``glue:Master``), SI units."""

    step: float = 1e-3
    tolerance: float = 1e-10
    relative_tolerance: float = 0.0
    max_iterations: int = 20
    predictor: str = "linear"
    refresh_after: int = 10
    refresh: str = "adaptive"
    convergence: str = "residual"
    coupling: str = "iterative"
    start: str = "auto"
    perturbation: float = 1e-3
    step_cuts: int = 4
    #: ``step="auto"``: the macro step is chosen at every step from an error estimate
    #: (:mod:`dsim.master.running.step_control`); ``step`` is then the output grid
    adaptive: bool = False
    #: the error an adaptive run keeps to, weighted E + E |x| per quantity (None: 1e-6)
    error_tolerance: float | None = None
    #: the smallest and largest macro step of an adaptive run, s (None: the output
    #: interval / 2**20 and the output interval)
    min_step: float | None = None
    max_step: float | None = None


@dataclass(frozen=True)
class Scene:
    """Everything a run needs from the SSP file."""

    name: str
    file: Path
    start_time: float
    stop_time: float
    components: tuple[Component, ...]
    connections: tuple[Connection, ...]
    joints: tuple[Joint, ...]
    port_maps: tuple[PortMap, ...]
    master: MasterSettings
    #: files read besides ``file`` and the FMUs (SystemStructure.ssd, .ssv, .ssm files)
    inputs: tuple[Path, ...] = ()
    #: the SSD's units by name
    units: dict = field(default_factory=dict)
    #: whether start and stop time came from a DefaultExperiment (else dsim's defaults)
    experiment: bool = True
    #: what the reader found wrong (a scene read with ``strict=False``: the plan adds
    #: its own findings and raises them all)
    problems: tuple[str, ...] = ()
    #: results the scene ships as its reference (``resources/reference.csv``: its
    #: monolithic twin's, docs/sweep.md), or None
    reference: Path | None = None
    #: component path -> the Ray resource whose node runs it (``glue:Placement``)
    placements: dict = field(default_factory=dict)
    #: rules the files break that do not change what the run computes (each one line;
    #: ``strict`` refuses them)
    warnings: tuple[str, ...] = ()
    #: the SSP version the SystemStructure.ssd declares (1.0, 2.0, ...)
    ssp_version: str = ""
    #: where the macro step came from: the step setting, glue:Master, another tool's
    #: annotation (dsim.master.reading.ssp_tools) or dsim's default (dsim info and validate say it)
    step_from: str = "dsim's default"
    #: the parameter sets chosen on top of the scene's bindings (``parameter_set``)
    parameter_sets: tuple[str, ...] = ()
    #: values given for this run on top of every binding (``parameters=``, ``--set``):
    #: full name -> the value applied (dsim.master.planning.parameters)
    overrides: dict = field(default_factory=dict)
    #: the ``glue:Master`` attributes as the file writes them, where they stand, and
    #: another tool's step where they give none ((text, where, origin) or ()): what
    #: :mod:`dsim.master.planning.load` converts into ``master`` and ``step_from``
    master_annotation: dict = field(default_factory=dict)
    master_where: str = ""
    other_step: tuple = ()
    #: FMU file -> its description (dsim.master.reading.fmi_description.FmuDescription),
    #: read with the scene for every FMU that passed the checks made without loading it
    descriptions: dict = field(default_factory=dict)

    def component(self, path: str) -> Component:
        """The component at a dotted path (KeyError: none is there)."""
        return self._by_path[path]

    @cached_property
    def _by_path(self) -> dict:
        """dotted path -> component, made once (a scan per look-up made validating
        10,000 components quadratic); the first of two with the same path wins."""
        index: dict = {}
        for component in self.components:
            index.setdefault(component.path, component)
        return index
