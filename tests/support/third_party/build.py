"""Compile the plain-C FMUs of this folder into real FMI 2.0 co-simulation FMUs with
gcc and the FMI 2.0 headers that fmpy ships (tests and benchmarks both use them)."""
from __future__ import annotations

import shutil
import subprocess
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path

import fmpy

HERE = Path(__file__).parent


@dataclass(frozen=True)
class Variable:
    """A scalar variable of a C FMU's modelDescription.xml."""

    name: str
    value_reference: int
    type: str = "Real"
    causality: str = "local"
    variability: str | None = None
    initial: str | None = None
    start: object = None

    def xml(self) -> str:
        attributes = [f'name="{self.name}"', f'valueReference="{self.value_reference}"',
                      f'causality="{self.causality}"']
        variability = self.variability or {"parameter": "fixed"}.get(
            self.causality, "discrete" if self.type != "Real" else "continuous")
        attributes.append(f'variability="{variability}"')
        if self.initial:
            attributes.append(f'initial="{self.initial}"')
        start = "" if self.start is None else f' start="{_text(self.start)}"'
        return f'    <ScalarVariable {" ".join(attributes)}><{self.type}{start}/></ScalarVariable>'


def _text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


#: the variables of block.c (value references as its enums number them)
BLOCK_VARIABLES = (
    Variable("gain", 0, causality="parameter", start=0.9),
    Variable("tau", 1, causality="parameter", start=0.1),
    Variable("y0", 2, causality="parameter", start=1.0),
    Variable("fail_time", 3, causality="parameter", start=1e300),
    Variable("u", 4, causality="input", start=0.0),
    Variable("y", 5, causality="output", initial="calculated"),
    Variable("failure", 0, "Integer", "parameter", start=0),
    Variable("extra", 1, "Integer", "input", start=0),
    Variable("count", 2, "Integer", "output", initial="calculated"),
    Variable("enable", 0, "Boolean", "input", start=True),
    Variable("positive", 1, "Boolean", "output", initial="calculated"),
    Variable("label", 0, "String", "parameter", start="block"),
    Variable("note", 1, "String", "input", start=""),
    Variable("status", 2, "String", "output", initial="calculated"),
)


def model_description(identifier: str, variables, can_save_state: bool = True,
                      variable_step: bool = True, log_categories=(),
                      interpolate_inputs: bool = False) -> str:
    """modelDescription.xml of a C FMU (the start values must be the C code's own),
    declaring ``log_categories`` (names) when given, and canInterpolateInputs="true"
    with ``interpolate_inputs``."""
    listed = list(variables)
    categories = "".join(f'<Category name="{c}"/>' for c in log_categories)
    categories = f"\n  <LogCategories>{categories}</LogCategories>" if categories else ""
    interpolates = ' canInterpolateInputs="true"' if interpolate_inputs else ""
    outputs = "".join(f'<Unknown index="{i + 1}"/>' for i, v in enumerate(listed)
                      if v.causality == "output")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="{identifier}" guid="{{{uuid.uuid4()}}}"
    variableNamingConvention="structured" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{identifier}"
      canHandleVariableCommunicationStepSize="{str(variable_step).lower()}"
      canGetAndSetFMUstate="{str(can_save_state).lower()}"{interpolates}/>{categories}
  <ModelVariables>
{chr(10).join(v.xml() for v in listed)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>{outputs}</Outputs>
    <InitialUnknowns>{outputs}</InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def compile_library(source: Path, library: Path, defines=()) -> Path:
    """gcc a C FMU source into a shared library (raises when there is no gcc)."""
    if shutil.which("gcc") is None:
        raise RuntimeError("no C compiler (gcc) on this machine")
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", *[f"-D{d}" for d in defines],
                    f"-I{headers}", str(source), "-o", str(library), "-lm"], check=True)
    return library


#: the variables of oscillator.c
OSCILLATOR_VARIABLES = (
    Variable("m", 0, causality="parameter", start=1.0),
    Variable("k", 1, causality="parameter", start=1.0),
    Variable("F_in", 2, causality="input", start=0.0),
    Variable("s", 3, causality="output", initial="calculated"),
    Variable("v", 4, causality="output", initial="calculated"),
    Variable("a", 5, causality="output", initial="calculated"),
    Variable("s0", 6, causality="parameter", start=0.0),
    Variable("h_max", 7, causality="parameter", start=0.0),
)


#: the variables of offset.c (libcosim's scenario test slave, with a tunable, a fixed and
#: a constant beside it; value references as its enums number them)
OFFSET_VARIABLES = (
    Variable("realOut", 0, causality="output", initial="calculated"),
    Variable("realIn", 1, causality="input", start=1.0),
    Variable("realInEcho", 2, causality="output", initial="calculated"),
    Variable("offset", 3, causality="parameter", variability="tunable", start=1.234),
    Variable("version", 4, causality="local", variability="constant", start=1.0),
    Variable("intOut", 0, "Integer", "output", initial="calculated"),
    Variable("intIn", 1, "Integer", "input", start=1),
    Variable("intInEcho", 2, "Integer", "output", initial="calculated"),
    Variable("intStep", 3, "Integer", "parameter", start=2),
    Variable("flag", 0, "Boolean", "input", start=False),
    Variable("flagOut", 1, "Boolean", "output", initial="calculated"),
    Variable("label", 0, "String", "input", start=""),
    Variable("labelOut", 1, "String", "output", initial="calculated"),
)


def c_fmu(folder: Path, name: str, source: str = "block.c", variables=BLOCK_VARIABLES,
          can_save_state: bool = True, variable_step: bool = True, defines=(),
          log_categories=(), interpolate_inputs: bool = False) -> Path:
    """Compile ``source`` (a file of this folder) and pack ``folder/name.fmu``; its
    model identifier is the source's stem; ``log_categories``: the LogCategories its
    description declares; ``interpolate_inputs``: it declares canInterpolateInputs
    (the C code's to honour: oscillator.c with the define INTERPOLATE)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    identifier = Path(source).stem
    library = folder / f"{name}.so"
    compile_library(HERE / source, library,
                    tuple(defines) + (() if can_save_state else ("NO_STATE",)))
    fmu = folder / f"{name}.fmu"
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.writestr("modelDescription.xml", model_description(
            identifier, variables, can_save_state, variable_step, log_categories,
            interpolate_inputs))
        archive.write(library, f"binaries/linux64/{identifier}.so")
    library.unlink()
    return fmu


def causal_ring_ssp(path: Path, fmu: Path, count: int, stop: float = 1.0,
                    step: float = 1e-3, integer_outputs=()) -> Path:
    """An .ssp of ``count`` block FMUs in a ring of causal connections (b1.y -> b2.u
    -> ... -> b<count>.y -> b1.u), every connector declared as fmpy's SSP runner
    needs (and the Integer outputs ``integer_outputs``, recorded); no parameter
    bindings (every block runs on its start values)."""
    names = [f"b{i + 1}" for i in range(count)]
    components = "\n".join(
        f'      <ssd:Component name="{n}" source="resources/block.fmu">\n'
        '        <ssd:Connectors>\n'
        '          <ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector>\n'
        '          <ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector>\n'
        + "".join(f'          <ssd:Connector name="{o}" kind="output"><ssc:Integer/>'
                  '</ssd:Connector>\n' for o in integer_outputs) +
        '        </ssd:Connectors>\n'
        '      </ssd:Component>' for n in names)
    connections = "\n".join(
        f'      <ssd:Connection startElement="{a}" startConnector="y" endElement="{b}" '
        'endConnector="u"/>' for a, b in zip(names, names[1:] + names[:1]))
    ssd = f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="ring_{count}"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssd:System name="root">
    <ssd:Elements>
{components}
    </ssd:Elements>
    <ssd:Connections>
{connections}
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="{stop!r}">
    <ssd:Annotations><ssc:Annotation type="org.dsim.master">
      <glue:Master xmlns:glue="urn:dsim:gluing:1" step="{step!r}"/>
    </ssc:Annotation></ssd:Annotations>
  </ssd:DefaultExperiment>
</ssd:SystemStructureDescription>
"""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("SystemStructure.ssd", ssd)
        archive.write(fmu, "resources/block.fmu")
    return path
