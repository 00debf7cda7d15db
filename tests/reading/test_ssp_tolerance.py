"""SSP files as other tools write them (OMSimulator, OpenModelica): what breaks a rule
without changing what the run computes is read with one warning line per finding
(`dsim validate` exits 0), and refused with --strict (exit 2)."""
import zipfile

import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.interop import block, connectors, system, values, write_scene

SSV = ('<?xml version="1.0" encoding="UTF-8"?>\n'
       '<ssv:ParameterSet version="{version}" name="{name}" '
       'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">'
       "<ssv:Parameters>{rows}</ssv:Parameters></ssv:ParameterSet>")


def ssv(name: str, version: str = "1.0", kind: str = "Real", **parameters) -> str:
    rows = "".join(f'<ssv:Parameter name="{key}"><ssv:{kind} value="{value!r}"/>'
                   "</ssv:Parameter>" for key, value in parameters.items())
    return SSV.format(version=version, name=name, rows=rows)


def check(folder, capsys, *warned: str) -> list[str]:
    """validate says each of ``warned`` in one warning line and exits 0; --strict
    refuses with the same lines as errors (exit 2).  The warning lines."""
    assert main(["validate", str(folder)]) == 0
    captured = capsys.readouterr()
    assert ": valid: " in captured.out
    warnings = captured.err.strip().splitlines()
    assert all(line.startswith("dsim: warning: ") for line in warnings)
    for text in warned:
        assert sum(text in line for line in warnings) == 1, (text, warnings)
    assert main(["validate", str(folder), "--strict"]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    for text in warned:
        assert sum(text in line and line.startswith("dsim: error: ") for line in errors) == 1
    with pytest.raises(dsim.InputError):
        dsim.prepare(folder, strict=True)
    return warnings


def gain_of(folder, component: str = "b1", **settings) -> float:
    plan = dsim.prepare(folder, **settings)
    return next(s for s in plan.specs if s.name == component).parameters["gain"][1]


def test_ssp_2_files_are_read_and_their_new_content_warned_about(block_fmus, tmp_path,
                                                                  capsys):
    """OMSimulator writes version="2.0" in the SSP 1.0 namespaces (SSP 2.0 keeps them):
    the SSD, a .ssv and an inline set; a 2.0 type (ssc:Float64) is one warning, and a
    value given as ssv:Float64 still applies."""
    folder = write_scene(
        tmp_path, system(block("b1", inside=connectors(("y", "output", "Float64", None))
                               + '<ssd:ParameterBindings><ssd:ParameterBinding '
                               'source="resources/gains.ssv"/></ssd:ParameterBindings>')),
        {"block.fmu": block_fmus["state"]},
        files={"resources/gains.ssv": ssv("gains", "2.0", "Float64", gain=0.25)})
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('version="1.0" name="interop"',
                                           'version="2.0" name="interop"', 1))
    check(folder, capsys, "SSP 2.0 content dsim does not use: Element "
          "'{http://ssp-standard.org/SSP1/SystemStructureCommon}Float64'")
    assert gain_of(folder) == 0.25
    assert main(["info", str(folder)]) == 0
    assert "SSP version 2.0" in capsys.readouterr().out
    # a 2.x version does not excuse what is wrong in SSP 1.0 too
    ssd.write_text(ssd.read_text().replace('startTime="0"', 'startTime="soon"'))
    assert main(["validate", str(folder)]) == 2
    assert "not valid SSP 1.0" in capsys.readouterr().err


def test_empty_mapping_entries_and_values_for_other_tools_are_warnings(block_fmus, tmp_path,
                                                                        capsys):
    """OMSimulator writes a MappingEntry with source="" per model parameter, and sets
    carry values that name no variable (CAD geometry): skipped, each said once."""
    mapping = ('<ssd:ParameterMapping><ssm:ParameterMapping>'
               + "".join(f'<ssm:MappingEntry source="" target="p{i}"/>' for i in range(300))
               + '<ssm:MappingEntry source="G" target="gain"/></ssm:ParameterMapping>'
               "</ssd:ParameterMapping>")
    folder = write_scene(tmp_path, system(block(
        "b1", inside='<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>'
        + values(G=0.5, cad_length=0.2) + f"</ssd:ParameterValues>{mapping}"
        "</ssd:ParameterBinding></ssd:ParameterBindings>"),
        inside="<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
        + values(**{"housing.width": 0.1}) + "</ssd:ParameterValues></ssd:ParameterBinding>"
        "</ssd:ParameterBindings>"), {"block.fmu": block_fmus["state"]})
    check(folder, capsys, "300 MappingEntry with an empty source skipped (targets p0, p1, p2",
          "parameter 'cad_length' is not a variable of component 'b1' (block.fmu): "
          "not applied",
          "parameter 'housing.width' names no component variable and no system connector")
    assert gain_of(folder) == 0.5
    result = dsim.simulate(folder)
    assert result.ok and len(result.warnings) == 3


def test_a_chosen_parameter_set_goes_through_the_scenes_mapping_for_it(block_fmus, tmp_path,
                                                                        capsys):
    """--parameter-set of a set the scene binds with a ParameterMapping (its names are
    the mapping's sources) applies it there, mapped, above every other binding."""
    bound = ('<ssd:ParameterBindings><ssd:ParameterBinding source="resources/tuned.ssv">'
             '<ssd:ParameterMapping><ssm:ParameterMapping><ssm:MappingEntry source="G" '
             'target="gain"/></ssm:ParameterMapping></ssd:ParameterMapping>'
             "</ssd:ParameterBinding></ssd:ParameterBindings>")
    root_binding = ("<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
                    + values(**{"b1.gain": 0.5}) + "</ssd:ParameterValues>"
                    "</ssd:ParameterBinding></ssd:ParameterBindings>")
    folder = write_scene(tmp_path, system(block("b1", inside=bound), inside=root_binding),
                         {"block.fmu": block_fmus["state"]},
                         files={"resources/tuned.ssv": ssv("tuned", G=0.75)})
    assert gain_of(folder) == 0.5  # the root system's binding wins, as SSP says
    assert gain_of(folder, parameter_set="tuned") == 0.75
    assert gain_of(folder, parameter_set="resources/tuned.ssv", strict=True) == 0.75
    assert main(["validate", str(folder), "--parameter-set", "tuned", "--strict"]) == 0


def test_non_real_continuous_variables_of_openmodelica_are_a_warning(block_fmus, tmp_path,
                                                                     capsys):
    """OpenModelica exports Enumeration variables variability="continuous" (FMI 2.0
    forbids it; fmpy refuses the description): read, run, said once."""
    fmu = tmp_path / "om.fmu"
    with zipfile.ZipFile(block_fmus["state"]) as old, zipfile.ZipFile(fmu, "w") as new:
        for name in old.namelist():
            data = old.read(name)
            if name == "modelDescription.xml":
                data = data.decode().replace(
                    "<ModelVariables>", '<TypeDefinitions><SimpleType name="Mode"><Enumeration>'
                    '<Item name="off" value="1"/><Item name="on" value="2"/></Enumeration>'
                    "</SimpleType></TypeDefinitions><ModelVariables>").replace(
                    "</ModelVariables>", '<ScalarVariable name="mode" valueReference="99" '
                    'causality="local" variability="continuous" initial="exact"><Enumeration '
                    'declaredType="Mode" start="1"/></ScalarVariable></ModelVariables>').encode()
            new.writestr(name, data)
    folder = write_scene(tmp_path / "scene", system(block("b1")), {"block.fmu": fmu})
    check(folder, capsys, "block.fmu: modelDescription.xml declares 1 non-Real variable(s) "
          'variability="continuous" (FMI 2.0 forbids it; it changes nothing dsim does): mode')
    result = dsim.simulate(folder)
    assert result.ok and result["b1.count"][-1] == 50


def test_model_exchange_implementation(block_fmus, tmp_path, capsys):
    """implementation="ModelExchange" on an FMU without that interface is refused in one
    line naming the component; an FMU with Model Exchange only is no longer refused for
    its interface (this fake one is refused for what it lacks: a binary)."""
    from tests.support.interop import fake_fmu

    me = ('<ssd:Component name="b1" source="resources/block.fmu" '
          'implementation="ModelExchange"/>')
    folder = write_scene(tmp_path / "both", system(me), {"block.fmu": block_fmus["state"]})
    assert main(["validate", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "Component 'b1'" in lines[0] and lines[0].endswith(
        'implementation="ModelExchange", but the FMU has CoSimulation')
    only = fake_fmu(tmp_path / "block.fmu", (
        '<?xml version="1.0"?><fmiModelDescription fmiVersion="2.0" modelName="b" '
        'guid="{x}"><ModelExchange modelIdentifier="b"/><ModelVariables>'
        '<ScalarVariable name="x" valueReference="0" causality="output" '
        'variability="continuous" initial="calculated"><Real/></ScalarVariable>'
        '</ModelVariables><ModelStructure><Outputs><Unknown index="1"/></Outputs>'
        "</ModelStructure></fmiModelDescription>"))
    folder = write_scene(tmp_path / "only", system(me), {"block.fmu": only})
    assert main(["validate", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "Component 'b1'" in lines[0] and "no binary" in lines[0]