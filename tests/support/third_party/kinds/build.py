"""Build the small plain-C FMUs of this folder for every kind of FMI: 1.0 Co-Simulation,
2.0 Model Exchange and/or Co-Simulation, 3.0 Model Exchange and/or Co-Simulation.

One C skeleton per FMI API (fmi1cs.c, fmi2.c, fmi3.c, sharing core.c) is compiled with
gcc, against the FMI headers fmpy ships, together with one model (models/<name>.c, the
interface is model.h); this module writes the matching modelDescription.xml and packs
``<folder>/<name>.fmu`` (``binaries/linux64/<identifier>.so``; FMI 3.0:
``binaries/x86_64-linux/``).  Each build has a fresh
guid (FMI 3.0: instantiationToken), compiled into the library, which checks it when
instantiated.

    build_fmu(folder, "bouncing_ball", fmi_version="3.0", interfaces=("ModelExchange",))

One FMU stands apart: typed_array (typed_array3.c, standalone, FMI 3.0 Co-Simulation
only) has arrays and variables of the FMI 3.0 types beyond Float64, which the skeletons
cannot have; :func:`build_typed_array` builds it.

:data:`MODELS` describes each model's variables (value references as the C file's
enum numbers them); its start values must be the C file's own (the tests check them).
"""
from __future__ import annotations

import platform
import re
import shutil
import subprocess
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import fmpy

HERE = Path(__file__).parent
MODEL_EXCHANGE, CO_SIMULATION = "ModelExchange", "CoSimulation"
FMI_VERSIONS = ("1.0", "2.0", "3.0")
#: value reference of the independent variable "time" (FMI 3.0 declares it)
TIME_VR = 1000
#: the skeleton of each FMI version
SKELETONS = {"1.0": "fmi1cs.c", "2.0": "fmi2.c", "3.0": "fmi3.c"}

#: SI base-unit exponents of the units the models use
UNITS = {
    "m": {"m": 1}, "m/s": {"m": 1, "s": -1}, "m/s2": {"m": 1, "s": -2},
    "kg": {"kg": 1}, "N": {"kg": 1, "m": 1, "s": -2}, "N/m": {"kg": 1, "s": -2},
    "N.s/m": {"kg": 1, "s": -1}, "s": {"s": 1},
}


@dataclass(frozen=True)
class Var:
    """A Real (Float64) variable of a model.

    ``causality``: parameter, input, output or local; parameters and inputs have a
    start value, every other variable is calculated (``initial="calculated"``).
    ``derivative``: the name of the state this variable is the derivative of.
    ``depends``: for an output or a state derivative, the inputs and states it depends
    on (None: not declared, it may depend on all)."""

    name: str
    vr: int
    causality: str = "local"
    start: float | None = None
    unit: str | None = None
    description: str = ""
    derivative: str | None = None
    depends: tuple[str, ...] | None = None
    discrete: bool = False


@dataclass(frozen=True)
class Model:
    """A model of models/<name>.c: its variables, its states in the C code's order and
    the variables whose values are its event indicators (FMI 3.0 names them)."""

    name: str
    description: str
    variables: tuple[Var, ...]
    states: tuple[str, ...] = ()
    event_indicators: tuple[str, ...] = ()
    stop_time: float = 1.0

    def __post_init__(self):
        assert [v.vr for v in self.variables] == list(range(len(self.variables)))

    @property
    def source(self) -> Path:
        return HERE / "models" / f"{self.name}.c"

    def var(self, name: str) -> Var:
        return next(v for v in self.variables if v.name == name)

    def derivative_of(self, state: str) -> Var:
        return next(v for v in self.variables if v.derivative == state)

    def initial_unknowns(self) -> list[Var]:
        """Outputs, states and state derivatives: all calculated at initialization."""
        names = {v.name for v in self.variables if v.causality == "output"}
        names |= set(self.states) | {self.derivative_of(s).name for s in self.states}
        return [v for v in self.variables if v.name in names]


def _p(name, vr, start, unit=None, description=""):
    return Var(name, vr, "parameter", start=start, unit=unit, description=description)


MODELS = {m.name: m for m in (
    Model("oscillator", "damped mass-spring oscillator driven by a force: "
          "m a = F - k x - d v", (
              _p("m", 0, 1.0, "kg", "mass"),
              _p("k", 1, 1.0, "N/m", "spring stiffness"),
              _p("d", 2, 0.0, "N.s/m", "damping"),
              _p("x0", 3, 1.0, "m", "initial position"),
              _p("v0", 4, 0.0, "m/s", "initial velocity"),
              Var("P.f_x", 5, "input", 0.0, "N", "external force F"),
              Var("P.u_x", 6, "output", unit="m", description="position x (a state)",
                  depends=("P.u_x",)),
              Var("P.v_x", 7, "output", unit="m/s", description="velocity v (a state)",
                  derivative="P.u_x", depends=("P.v_x",)),
              Var("P.a_x", 8, "output", unit="m/s2", description="acceleration",
                  derivative="P.v_x", depends=("P.f_x", "P.u_x", "P.v_x")),
          ), states=("P.u_x", "P.v_x"), stop_time=10.0),
    Model("bouncing_ball", "a ball bouncing on the ground: h' = v, v' = -g; "
          "at h = 0 going down v := -e v", (
              _p("g", 0, 9.81, "m/s2", "gravity"),
              _p("e", 1, 0.7, None, "coefficient of restitution"),
              _p("h0", 2, 1.0, "m", "initial height"),
              _p("v_min", 3, 0.1, "m/s", "slowest rebound (slower: the ball rests)"),
              Var("h", 4, "output", unit="m", description="height (a state)",
                  depends=("h",)),
              Var("v", 5, "output", unit="m/s", description="velocity (a state)",
                  derivative="h", depends=("v",)),
              Var("der(v)", 6, unit="m/s2", description="acceleration",
                  derivative="v", depends=()),
          ), states=("h", "v"), event_indicators=("h",), stop_time=3.0),
    Model("time_event", "x' = r, r = 1 before the time event at T and -1 after", (
        _p("T", 0, 0.5, "s", "time of the switch"),
        Var("x", 1, "output", description="the integral of r (a state)",
            depends=("x",)),
        Var("r", 2, "output", description="rate: 1 before T, -1 after", depends=(),
            discrete=True),
        Var("der(x)", 3, description="derivative of x", derivative="x", depends=()),
    ), states=("x",), stop_time=1.0),
    Model("feedthrough", "a static gain with offset: y = g u + c", (
        _p("g", 0, 0.5, None, "gain"),
        _p("c", 1, 1.0, None, "offset"),
        Var("u", 2, "input", 0.0, description="input"),
        Var("y", 3, "output", description="g u + c", depends=("u",)),
    ), stop_time=1.0),
    Model("mass1", "two-mass oscillator, mass 1: m1 a1 = F - k1 x1 - d1 v1", (
        _p("m1", 0, 1.0, "kg", "mass 1"),
        _p("k1", 1, 10.0, "N/m", "spring of mass 1 to ground"),
        _p("d1", 2, 0.0, "N.s/m", "damper of mass 1 to ground"),
        _p("x1_0", 3, 0.1, "m", "initial position"),
        _p("v1_0", 4, 0.0, "m/s", "initial velocity"),
        Var("F", 5, "input", 0.0, "N", "coupling force on mass 1"),
        Var("x1", 6, "output", unit="m", description="position (a state)",
            depends=("x1",)),
        Var("v1", 7, "output", unit="m/s", description="velocity (a state)",
            derivative="x1", depends=("v1",)),
        Var("a1", 8, "output", unit="m/s2", description="acceleration",
            derivative="v1", depends=("F", "x1", "v1")),
    ), states=("x1", "v1"), stop_time=2.0),
    Model("mass2", "two-mass oscillator, mass 2 and the coupling: "
          "Fc = kc (x2 - x1) + dc (v2 - v1), m2 a2 = -k2 x2 - d2 v2 - Fc", (
              _p("m2", 0, 1.0, "kg", "mass 2"),
              _p("k2", 1, 10.0, "N/m", "spring of mass 2 to ground"),
              _p("d2", 2, 0.0, "N.s/m", "damper of mass 2 to ground"),
              _p("kc", 3, 100.0, "N/m", "coupling spring"),
              _p("dc", 4, 0.0, "N.s/m", "coupling damper"),
              _p("x2_0", 5, 0.0, "m", "initial position"),
              _p("v2_0", 6, 0.0, "m/s", "initial velocity"),
              Var("x1", 7, "input", 0.0, "m", "position of mass 1"),
              Var("v1", 8, "input", 0.0, "m/s", "velocity of mass 1"),
              Var("F", 9, "output", unit="N", description="coupling force on mass 1",
                  depends=("x1", "v1", "x2", "v2")),
              Var("x2", 10, "output", unit="m", description="position (a state)",
                  depends=("x2",)),
              Var("v2", 11, "output", unit="m/s", description="velocity (a state)",
                  derivative="x2", depends=("v2",)),
              Var("a2", 12, "output", unit="m/s2", description="acceleration",
                  derivative="v2", depends=("x1", "v1", "x2", "v2")),
          ), states=("x2", "v2"), stop_time=2.0),
)}


#: OMSimulator's equationPair test as two FMUs (models/equation1.c, equation2.c): a
#: nonlinear algebraic loop across them, x2 = (42 - 2 x1^2) / 5 and x1 = 4 + 6 x2
#: (not in :data:`MODELS`: the loop tests build them, the per-model tests need not)
EQUATION_PAIR = {m.name: m for m in (
    Model("equation1", "2 x1^2 + 5 x2 = 42 solved for x2", (
        Var("x1", 0, "input", 4.0, description="input"),
        Var("x2", 1, "output", description="(42 - 2 x1^2) / 5", depends=("x1",)),
    ), stop_time=1.0),
    Model("equation2", "x1 - 6 x2 = 4 solved for x1", (
        Var("x2", 0, "input", 8.4, description="input"),
        Var("x1", 1, "output", description="4 + 6 x2", depends=("x2",)),
    ), stop_time=1.0),
)}


def _model(model) -> Model:
    return model if isinstance(model, Model) else MODELS[model]


def _bool(value: bool) -> str:
    return "true" if value else "false"


def _attrs(**attributes) -> str:
    return " ".join(f"{k}={quoteattr(str(v))}" for k, v in attributes.items()
                    if v is not None)


def _variability(v: Var) -> str:
    return "fixed" if v.causality == "parameter" else (
        "discrete" if v.discrete else "continuous")


def _units_xml(model: Model, fmi_version: str) -> str:
    used = sorted({v.unit for v in model.variables if v.unit})
    if not used:
        return ""
    if fmi_version == "1.0":
        units = "".join(f'\n    <BaseUnit unit="{u}"/>' for u in used)
    else:
        units = "".join(f'\n    <Unit name="{u}"><BaseUnit {_attrs(**UNITS[u])}/></Unit>'
                        for u in used)
    return f"  <UnitDefinitions>{units}\n  </UnitDefinitions>\n"


def _experiment(model: Model) -> str:
    return f'  <DefaultExperiment startTime="0" stopTime="{model.stop_time!r}"/>'


def _check(fmi_version: str, interfaces) -> tuple[str, ...]:
    interfaces = tuple(interfaces)
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"FMI version {fmi_version!r} is not one of {FMI_VERSIONS}")
    if not interfaces or set(interfaces) - {MODEL_EXCHANGE, CO_SIMULATION}:
        raise ValueError(f"interfaces {interfaces!r}: ModelExchange and/or CoSimulation")
    if fmi_version == "1.0" and interfaces != (CO_SIMULATION,):
        raise ValueError("FMI 1.0 is built for Co-Simulation only")
    return interfaces


def model_description(model, fmi_version: str = "2.0",
                      interfaces=(MODEL_EXCHANGE, CO_SIMULATION),
                      can_save_state: bool = True, identifier: str | None = None,
                      guid: str | None = None) -> str:
    """The modelDescription.xml of ``model`` (a name of :data:`MODELS` or a Model)."""
    model = _model(model)
    interfaces = _check(fmi_version, interfaces)
    identifier = identifier or model.name
    guid = guid or f"{{{uuid.uuid4()}}}"
    writer = {"1.0": _fmi1_xml, "2.0": _fmi2_xml, "3.0": _fmi3_xml}[fmi_version]
    return writer(model, interfaces, can_save_state, identifier, guid)


def _header(model: Model, identifier: str) -> str:
    return (f'modelName="{identifier}" description={quoteattr(model.description)} '
            'generationTool="dsim tests/support/third_party/kinds" '
            'variableNamingConvention="structured"')


def _fmi1_xml(model, interfaces, can_save_state, identifier, guid) -> str:
    lines = []
    for v in model.variables:
        causality = {"parameter": "internal", "local": "internal"}.get(v.causality,
                                                                       v.causality)
        variability = ("parameter" if v.causality == "parameter" else
                       "discrete" if v.discrete else "continuous")
        real = _attrs(start=None if v.start is None else repr(float(v.start)), unit=v.unit)
        dependency = ""
        if v.causality == "output" and v.depends is not None:
            names = "".join(f"<Name>{d}</Name>" for d in v.depends
                            if model.var(d).causality == "input")
            dependency = f"<DirectDependency>{names}</DirectDependency>"
        lines.append(f'    <ScalarVariable {_attrs(name=v.name, valueReference=v.vr)} '
                     f'description={quoteattr(v.description)} variability="{variability}" '
                     f'causality="{causality}"><Real {real}/>{dependency}</ScalarVariable>')
    variables = "\n".join(lines)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="1.0" {_header(model, identifier)}
    modelIdentifier="{identifier}" guid="{guid}"
    numberOfContinuousStates="{len(model.states)}"
    numberOfEventIndicators="{len(model.event_indicators)}">
{_units_xml(model, "1.0")}{_experiment(model)}
  <ModelVariables>
{variables}
  </ModelVariables>
  <Implementation>
    <CoSimulation_StandAlone>
      <Capabilities canHandleVariableCommunicationStepSize="true" canHandleEvents="true"
          canRejectSteps="false" canInterpolateInputs="true" maxOutputDerivativeOrder="0"
          canRunAsynchronuously="false" canSignalEvents="false"
          canBeInstantiatedOnlyOncePerProcess="false"
          canNotUseMemoryManagementFunctions="true"/>
    </CoSimulation_StandAlone>
  </Implementation>
</fmiModelDescription>
"""


def _structure_attrs(model: Model, v: Var, ref) -> str:
    """dependencies/dependenciesKind of an output or derivative (ref: name -> text)."""
    if v.depends is None:
        return ""
    return (f' dependencies="{" ".join(ref(d) for d in v.depends)}"'
            f' dependenciesKind="{" ".join("dependent" for _ in v.depends)}"')


def _fmi2_xml(model, interfaces, can_save_state, identifier, guid) -> str:
    index = {v.name: str(i + 1) for i, v in enumerate(model.variables)}
    state = _bool(can_save_state)
    common = (f'modelIdentifier="{identifier}" canGetAndSetFMUstate="{state}" '
              f'canSerializeFMUstate="{state}" providesDirectionalDerivative="false" '
              'canNotUseMemoryManagementFunctions="true"')
    kinds = ""
    if MODEL_EXCHANGE in interfaces:
        kinds += f"  <ModelExchange {common}/>\n"
    if CO_SIMULATION in interfaces:
        kinds += (f'  <CoSimulation {common}\n      canHandleVariableCommunicationStepSize='
                  '"true" canInterpolateInputs="true" maxOutputDerivativeOrder="0"/>\n')
    lines = []
    for v in model.variables:
        initial = "calculated" if v.causality in ("output", "local") else None
        real = _attrs(start=None if v.start is None else repr(float(v.start)), unit=v.unit,
                      derivative=index[v.derivative] if v.derivative else None)
        lines.append(f"    <ScalarVariable {_attrs(name=v.name, valueReference=v.vr)} "
                     f"description={quoteattr(v.description)} "
                     f"{_attrs(causality=v.causality, variability=_variability(v))}"
                     f"{' initial=' + quoteattr(initial) if initial else ''}>"
                     f"<Real {real}/></ScalarVariable>")
    ref = index.__getitem__
    outputs = "".join(f'\n      <Unknown index="{index[v.name]}"'
                      f'{_structure_attrs(model, v, ref)}/>'
                      for v in model.variables if v.causality == "output")
    derivatives = "".join(
        f'\n      <Unknown index="{index[d.name]}"{_structure_attrs(model, d, ref)}/>'
        for d in (model.derivative_of(s) for s in model.states))
    initial = "".join(f'\n      <Unknown index="{index[v.name]}"/>'
                      for v in model.initial_unknowns())
    structure = "".join(f"\n    <{tag}>{body}\n    </{tag}>" for tag, body in (
        ("Outputs", outputs), ("Derivatives", derivatives), ("InitialUnknowns", initial))
        if body)
    variables = "\n".join(lines)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" {_header(model, identifier)}
    guid="{guid}" numberOfEventIndicators="{len(model.event_indicators)}">
{kinds}{_units_xml(model, "2.0")}{_experiment(model)}
  <ModelVariables>
{variables}
  </ModelVariables>
  <ModelStructure>{structure}
  </ModelStructure>
</fmiModelDescription>
"""


def _fmi3_xml(model, interfaces, can_save_state, identifier, guid) -> str:
    state = _bool(can_save_state)
    common = (f'modelIdentifier="{identifier}" canGetAndSetFMUState="{state}" '
              f'canSerializeFMUState="{state}" providesDirectionalDerivatives="false" '
              'providesAdjointDerivatives="false"')
    kinds = ""
    if MODEL_EXCHANGE in interfaces:
        kinds += f'  <ModelExchange {common}\n      needsCompletedIntegratorStep="true"/>\n'
    if CO_SIMULATION in interfaces:
        kinds += (f'  <CoSimulation {common}\n      canHandleVariableCommunicationStepSize='
                  '"true" hasEventMode="false" maxOutputDerivativeOrder="0"\n'
                  '      providesIntermediateUpdate="false" '
                  'mightReturnEarlyFromDoStep="false"\n'
                  '      canReturnEarlyAfterIntermediateUpdate="false" '
                  'providesEvaluateDiscreteStates="false"/>\n')
    vr = {v.name: str(v.vr) for v in model.variables}
    lines = [f'    <Float64 name="time" valueReference="{TIME_VR}" causality="independent" '
             'variability="continuous" description="simulation time"/>']
    for v in model.variables:
        initial = "calculated" if v.causality in ("output", "local") else None
        lines.append("    <Float64 " + _attrs(
            name=v.name, valueReference=v.vr, description=v.description,
            causality=v.causality, variability=_variability(v), initial=initial,
            start=None if v.start is None else repr(float(v.start)), unit=v.unit,
            derivative=vr[v.derivative] if v.derivative else None) + "/>")
    ref = vr.__getitem__
    structure = "".join(
        f'\n    <Output valueReference="{v.vr}"{_structure_attrs(model, v, ref)}/>'
        for v in model.variables if v.causality == "output")
    structure += "".join(
        f'\n    <ContinuousStateDerivative valueReference="{d.vr}"'
        f'{_structure_attrs(model, d, ref)}/>'
        for d in (model.derivative_of(s) for s in model.states))
    structure += "".join(f'\n    <InitialUnknown valueReference="{v.vr}"/>'
                         for v in model.initial_unknowns())
    structure += "".join(f'\n    <EventIndicator valueReference="{vr[name]}"/>'
                         for name in model.event_indicators)
    variables = "\n".join(lines)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" {_header(model, identifier)}
    instantiationToken="{guid}">
{kinds}{_units_xml(model, "3.0")}{_experiment(model)}
  <ModelVariables>
{variables}
  </ModelVariables>
  <ModelStructure>{structure}
  </ModelStructure>
</fmiModelDescription>
"""


def compile_library(model, fmi_version: str, library: Path, identifier: str, guid: str,
                    can_save_state: bool = True, defines=()) -> Path:
    """gcc the skeleton of ``fmi_version``, core.c and the model into a shared library
    that exports the FMI functions only (raises when there is no gcc)."""
    if shutil.which("gcc") is None:
        raise RuntimeError("no C compiler (gcc) on this machine")
    model = _model(model)
    headers = Path(fmpy.__file__).parent / "c-code"
    flags = [f"-DMODEL_IDENTIFIER={identifier}", f'-DMODEL_GUID="{guid}"',
             f"-DTIME_VR={TIME_VR}", *[f"-D{d}" for d in defines]]
    if not can_save_state:
        flags.append("-DNO_STATE")
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", "-std=c99", "-fvisibility=hidden",
                    *flags, f"-I{headers}", f"-I{HERE}", str(HERE / SKELETONS[fmi_version]),
                    str(HERE / "core.c"), str(model.source), "-o", str(library), "-lm"],
                   check=True)
    return library


def _platform(fmi_version: str) -> str:
    """The binaries/ folder of this machine's libraries."""
    if fmi_version == "3.0":
        return f"{platform.machine()}-linux"
    return "linux64" if platform.architecture()[0] == "64bit" else "linux32"


def build_fmu(folder, model, fmi_version: str = "2.0",
              interfaces=(MODEL_EXCHANGE, CO_SIMULATION), can_save_state: bool = True,
              name: str | None = None, identifier: str | None = None,
              defines=()) -> Path:
    """Compile ``model`` (a name of :data:`MODELS` or a Model) for ``fmi_version``
    ("1.0": Co-Simulation only; "2.0", "3.0": ``interfaces``, one binary for both) and
    pack ``folder/<name>.fmu``.  ``identifier`` (the model identifier, default the
    model's name) names the library and, for FMI 1.0, prefixes the functions; ``name``
    defaults to it.  With ``can_save_state=False`` the FMU declares and implements no
    FMU-state saving.  ``defines``: extra C preprocessor definitions."""
    model = _model(model)
    interfaces = _check(fmi_version, interfaces)
    identifier = identifier or model.name
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", identifier):
        raise ValueError(f"model identifier {identifier!r} is not a C identifier")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = name or identifier
    guid = f"{{{uuid.uuid4()}}}"
    library = folder / f"{name}.so"
    compile_library(model, fmi_version, library, identifier, guid, can_save_state, defines)
    fmu = folder / f"{name}.fmu"
    try:
        with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml", model_description(
                model, fmi_version, interfaces, can_save_state, identifier, guid))
            archive.write(library, f"binaries/{_platform(fmi_version)}/{identifier}.so")
    finally:
        library.unlink()
    return fmu


def add_enumeration_output(fmu: Path, name: str, vr: int, type_name: str,
                           items: dict) -> Path:
    """Declare in the FMI 3.0 ``fmu`` (built with ``defines=("ENUM_VR=<vr>",
    "ENUM_OF=<a Real's vr>")``, which makes fmi3.c answer fmi3GetInt64 there) a discrete
    Enumeration output ``name`` at ``vr`` of the EnumerationType ``type_name`` with
    ``items`` (name -> value); rewrites the archive in place."""
    with zipfile.ZipFile(fmu) as archive:
        entries = {info.filename: archive.read(info) for info in archive.infolist()}
    text = entries["modelDescription.xml"].decode()
    listed = "".join(f'<Item name="{item}" value="{value}"/>' for item, value in items.items())
    text = text.replace("  <DefaultExperiment", f'  <TypeDefinitions><EnumerationType '
                        f'name="{type_name}">{listed}</EnumerationType></TypeDefinitions>\n'
                        "  <DefaultExperiment", 1)
    text = text.replace("  </ModelVariables>", f'    <Enumeration name="{name}" '
                        f'valueReference="{vr}" declaredType="{type_name}" causality="output" '
                        'variability="discrete" initial="calculated"/>\n  </ModelVariables>', 1)
    # the ModelStructure's order: Outputs, derivatives, InitialUnknowns, EventIndicators
    output = f'<Output valueReference="{vr}" dependencies="" dependenciesKind=""/>\n    '
    unknown = f'<InitialUnknown valueReference="{vr}"/>\n    '
    before = min(text.find(tag) for tag in ("<ContinuousStateDerivative", "<InitialUnknown",
                                            "</ModelStructure>") if tag in text)
    text = text[:before] + output + text[before:]
    before = min(text.find(tag) for tag in ("<EventIndicator", "</ModelStructure>")
                 if tag in text)
    text = text[:before] + unknown + text[before:]
    entries["modelDescription.xml"] = text.encode()
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for entry, data in entries.items():
            archive.writestr(entry, data)
    return fmu


def build_memcheck(folder, model, fmi_version: str = "2.0", can_save_state: bool = True,
                   name: str | None = None) -> Path:
    """Compile memcheck.c with the skeleton of ``fmi_version``, core.c and ``model``
    into an executable instrumented with AddressSanitizer, LeakSanitizer and
    UndefinedBehaviorSanitizer; running it drives the FMU through its API and exits
    with 0 when nothing went wrong (raises when gcc or its sanitizers are missing)."""
    if shutil.which("gcc") is None:
        raise RuntimeError("no C compiler (gcc) on this machine")
    model = _model(model)
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"FMI version {fmi_version!r} is not one of {FMI_VERSIONS}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    program = folder / (name or f"memcheck_{model.name}_{fmi_version[0]}")
    headers = Path(fmpy.__file__).parent / "c-code"
    flags = [f"-DFMI_VERSION={fmi_version[0]}", f"-DMODEL_IDENTIFIER={model.name}",
             f'-DMODEL_GUID="{{{uuid.uuid4()}}}"', f"-DTIME_VR={TIME_VR}"]
    if not can_save_state:
        flags.append("-DNO_STATE")
    subprocess.run(["gcc", "-g", "-O1", "-std=c99", "-fsanitize=address,undefined",
                    "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", *flags,
                    f"-I{headers}", f"-I{HERE}", str(HERE / "memcheck.c"),
                    str(HERE / SKELETONS[fmi_version]), str(HERE / "core.c"),
                    str(model.source), "-o", str(program), "-lm"],
                   check=True, capture_output=True, text=True)
    return program


# ---- typed_array: the FMI 3.0 Co-Simulation FMU of typed_array3.c ----

#: the variables of typed_array3.c (its enum numbers the same value references):
#: name -> (value reference, FMI 3.0 type, size (an array: > 1), start or None)
TYPED_ARRAY_VARIABLES = {
    "time": (TIME_VR, "Float64", 1, None),
    "k": (1, "Float64", 3, (1.0, 2.0, 3.0)),
    "u": (2, "Float64", 3, (0.0, 0.0, 0.0)),
    "x": (3, "Float64", 3, None),
    "x_sum": (4, "Float32", 1, None),
    "steps": (5, "Int32", 1, None),
    "offset": (6, "Int64", 1, 0),
    "positive": (7, "Boolean", 1, None),
    "label": (8, "String", 1, "typed"),
    "status": (9, "String", 1, None),
    "mode": (10, "Enumeration", 1, None),
    "gain8": (11, "UInt8", 1, 1),
}
#: the items of typed_array's EnumerationType "Mode" (the type of "mode")
TYPED_ARRAY_MODES = {"Off": 1, "On": 2}


def typed_array_description(guid: str, can_save_state: bool = True,
                            identifier: str = "typed_array") -> str:
    """The modelDescription.xml of typed_array3.c (FMI 3.0, Co-Simulation only)."""
    state = _bool(can_save_state)
    vr = {name: v[0] for name, v in TYPED_ARRAY_VARIABLES.items()}
    array = '><Dimension start="3"/></Float64>'
    variables = f"""\
    <Float64 name="time" valueReference="{vr['time']}" causality="independent"
        variability="continuous" description="simulation time"/>
    <Float64 name="k" valueReference="{vr['k']}" causality="parameter" variability="fixed"
        description="decay rates" start="1 2 3"{array}
    <Float64 name="u" valueReference="{vr['u']}" causality="input"
        description="inputs, held over a step" start="0 0 0"{array}
    <Float64 name="x" valueReference="{vr['x']}" causality="output" initial="calculated"
        description="the states: x' = -k x + gain8 u, x(start) = 1"{array}
    <Float32 name="x_sum" valueReference="{vr['x_sum']}" causality="output"
        initial="calculated" description="the sum of x"/>
    <Int32 name="steps" valueReference="{vr['steps']}" causality="output"
        variability="discrete" initial="calculated"
        description="the number of fmi3DoStep calls plus offset"/>
    <Int64 name="offset" valueReference="{vr['offset']}" causality="parameter"
        variability="fixed" start="0" description="added to steps"/>
    <Boolean name="positive" valueReference="{vr['positive']}" causality="output"
        variability="discrete" initial="calculated" description="x_sum &gt; 0"/>
    <String name="label" valueReference="{vr['label']}" causality="parameter"
        variability="fixed" description="the prefix of status">
      <Start value="typed"/>
    </String>
    <String name="status" valueReference="{vr['status']}" causality="output"
        variability="discrete" initial="calculated" description="label:steps"/>
    <Enumeration name="mode" valueReference="{vr['mode']}" declaredType="Mode"
        causality="output" variability="discrete" initial="calculated"
        description="On when some u is not 0, else Off"/>
    <UInt8 name="gain8" valueReference="{vr['gain8']}" causality="input"
        variability="discrete" start="1" description="the gain of u"/>"""
    outputs = ("x", "x_sum", "steps", "positive", "status", "mode")
    structure = "".join(
        f'\n    <Output valueReference="{vr[name]}" dependencies="{vr["u"]}"'
        ' dependenciesKind="dependent"/>' if name == "mode" else
        f'\n    <Output valueReference="{vr[name]}" dependencies="" dependenciesKind=""/>'
        for name in outputs)
    structure += "".join(f'\n    <InitialUnknown valueReference="{vr[name]}"/>'
                         for name in outputs)
    items = "".join(f'\n      <Item name="{name}" value="{value}"/>'
                    for name, value in TYPED_ARRAY_MODES.items())
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="{identifier}"
    description="x' = -k x + gain8 u for arrays of 3, with outputs of every kind"
    generationTool="dsim tests/support/third_party/kinds" variableNamingConvention="structured"
    instantiationToken="{guid}">
  <CoSimulation modelIdentifier="{identifier}" canGetAndSetFMUState="{state}"
      canSerializeFMUState="{state}" providesDirectionalDerivatives="false"
      providesAdjointDerivatives="false" canHandleVariableCommunicationStepSize="true"
      hasEventMode="false" maxOutputDerivativeOrder="0" providesIntermediateUpdate="false"
      mightReturnEarlyFromDoStep="false" canReturnEarlyAfterIntermediateUpdate="false"
      providesEvaluateDiscreteStates="false"/>
  <TypeDefinitions>
    <EnumerationType name="Mode">{items}
    </EnumerationType>
  </TypeDefinitions>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.01"/>
  <ModelVariables>
{variables}
  </ModelVariables>
  <ModelStructure>{structure}
  </ModelStructure>
</fmiModelDescription>
"""


def build_typed_array(folder, can_save_state: bool = True) -> Path:
    """Compile typed_array3.c (a standalone FMI 3.0 Co-Simulation FMU: arrays and every
    FMI 3.0 type but binaries and clocks, see :data:`TYPED_ARRAY_VARIABLES`) and pack
    ``folder/typed_array.fmu`` (``binaries/x86_64-linux/typed_array.so``, a fresh
    instantiationToken checked when instantiated).  With ``can_save_state=False``:
    ``folder/typed_array_nostate.fmu``, which declares and implements no FMU-state
    saving (raises when there is no gcc)."""
    if shutil.which("gcc") is None:
        raise RuntimeError("no C compiler (gcc) on this machine")
    identifier = "typed_array"
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    name = identifier if can_save_state else f"{identifier}_nostate"
    guid = f"{{{uuid.uuid4()}}}"
    headers = Path(fmpy.__file__).parent / "c-code"
    library = folder / f"{name}.so"
    flags = [f'-DMODEL_GUID="{guid}"'] + ([] if can_save_state else ["-DNO_STATE"])
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", "-std=c99", "-fvisibility=hidden",
                    *flags, f"-I{headers}", str(HERE / "typed_array3.c"),
                    "-o", str(library), "-lm"], check=True)
    fmu = folder / f"{name}.fmu"
    try:
        with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml",
                             typed_array_description(guid, can_save_state, identifier))
            archive.write(library, f"binaries/{_platform('3.0')}/{identifier}.so")
    finally:
        library.unlink()
    return fmu


def mass_fmus(folder, **options) -> dict:
    """The two halves of the two-mass oscillator (models/mass1.c, mass2.c) as FMI 2.0
    FMUs in ``folder``, built by :func:`build_fmu` with ``options``: name -> .fmu."""
    folder = Path(folder)
    return {name: build_fmu(folder / name, name, "2.0", **options)
            for name in ("mass1", "mass2")}
