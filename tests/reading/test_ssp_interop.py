"""SSP 1.0 as other tools write it, run with third-party C FMUs compiled here: Integer
and Boolean connections, mapping transformations, units, parameter bindings at
every level with mappings and prefixes, system connectors across levels,
connections applied at initialization, FMI's rules on start values, capabilities,
and FMUs dsim does not run.  Results against the blocks' exact update."""
import math
import shutil
import zipfile

import numpy as np
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.interop import (binding, block, connection, connectors, fake_fmu, system,
                                   values, write_scene)
from tests.support.third_party.build import c_fmu

H, TAU, GAIN = 1e-3, 0.1, 0.9
DECAY = math.exp(-H / TAU)


def lag(steps: int, y0: float, target) -> np.ndarray:
    """The block's exact update y <- g (u + e) + (y - g (u + e)) exp(-h/tau), with
    ``target(n, y)`` giving g (u + e) for step n from the state before it."""
    y, result = y0, [y0]
    for n in range(steps):
        goal = target(n, y)
        y = goal + (y - goal) * DECAY
        result.append(y)
    return np.array(result)


@pytest.fixture(scope="module")
def fmus(block_fmus, tmp_path_factory):
    folder = tmp_path_factory.mktemp("fixed")
    return {**block_fmus, "fixed_step": c_fmu(folder, "block_fixed", variable_step=False)}


def test_integer_and_boolean_connections(fmus, tmp_path):
    """b1.count (Integer) feeds b2.extra, b1.positive (Boolean) b2.enable; every
    Integer and Boolean output is a CSV column."""
    folder = write_scene(tmp_path, system(
        block("b1") + block("b2"),
        connection("b1", "count", "b2", "extra") + connection("b1", "positive", "b2", "enable")),
        {"block.fmu": fmus["state"]})
    result = dsim.simulate(folder)
    assert result.ok and result.statistics["coupling"] == "causal"
    assert np.array_equal(result["b1.count"], np.arange(51))
    assert np.array_equal(result["b1.positive"], np.ones(51))
    b1 = lag(50, 1.0, lambda n, y: 0.0)
    b2 = lag(50, 1.0, lambda n, y: GAIN * n)  # extra = b1's count at the step start
    assert np.max(np.abs(result["b1.y"] - b1)) < 1e-15
    assert np.max(np.abs(result["b2.y"] - b2)) < 1e-14


def test_string_parameters_connections_and_columns(fmus, tmp_path):
    """b1.status ("label:note:count", a String output) feeds b2.note; both statuses are
    CSV columns, read back as text, and kept in the .mat file."""
    folder = write_scene(tmp_path, system(
        block("b1", inside="<ssd:ParameterBindings>" + binding(label="first")
              + "</ssd:ParameterBindings>")
        + block("b2", inside="<ssd:ParameterBindings>" + binding(label="sec,ond \"2\"")
                + "</ssd:ParameterBindings>"),
        connection("b1", "status", "b2", "note")), {"block.fmu": fmus["state"]}, stop=0.003)
    result = dsim.simulate(folder, out=tmp_path / "run.csv", mat=tmp_path / "run.mat")
    assert list(result["b1.status"]) == [f"first::{n}" for n in range(4)]
    # b2's note is b1's status at the step start
    assert list(result["b2.status"]) == ['sec,ond "2"::0'] + [
        f'sec,ond "2":first::{n}:{n + 1}' for n in range(3)]
    from dsim.master.recording.results import read_columns
    from scipy.io import loadmat
    assert list(read_columns(tmp_path / "run.csv")["b2.status"]) == list(result["b2.status"])
    stored = loadmat(tmp_path / "run.mat")["signals"][0, 0]["b1_status"]
    assert [str(v[0]) for v in stored.ravel()] == list(result["b1.status"])
    assert main(["compare", str(tmp_path / "run.csv"), str(tmp_path / "run.csv")]) == 0


def test_mapping_transformations(fmus, tmp_path, capsys):
    boolean = ('<ssc:BooleanMappingTransformation><ssc:MapEntry source="true" target="false"/>'
               '<ssc:MapEntry source="false" target="true"/></ssc:BooleanMappingTransformation>')
    integer = ("<ssc:IntegerMappingTransformation>" + "".join(
        f'<ssc:MapEntry source="{n}" target="{10 * n}"/>' for n in range(5))
        + "</ssc:IntegerMappingTransformation>")
    folder = write_scene(tmp_path / "boolean", system(
        block("b1") + block("b2", inside=f"<ssd:ParameterBindings>{binding(u=1.0)}"
                                         "</ssd:ParameterBindings>"),
        connection("b1", "positive", "b2", "enable", boolean)), {"block.fmu": fmus["state"]})
    held = dsim.simulate(folder)
    assert held.ok and np.all(held["b2.y"] == 1.0)  # b1 positive -> b2 never enabled
    folder = write_scene(tmp_path / "integer", system(
        block("b1") + block("b2"), connection("b1", "count", "b2", "extra", integer)),
        {"block.fmu": fmus["state"]})
    assert main(["run", str(folder), "--out", str(tmp_path / "r.csv"), "--quiet"]) == 1
    line = capsys.readouterr().err.splitlines()[0]
    assert line == ("dsim: simulation failed: step 6 (t = 0.006 s): connection 'b1.count' -> "
                    "'b2.extra': its mapping has no entry for the value 5")
    result = dsim.read_columns(tmp_path / "r.csv")
    b2 = lag(5, 1.0, lambda n, y: GAIN * 10 * n)
    assert np.max(np.abs(result["b2.y"] - b2)) < 1e-13  # b2.y through the table


UNITS = ('<ssd:Units><ssc:Unit name="km"><ssc:BaseUnit m="1" factor="1000"/></ssc:Unit>'
         '<ssc:Unit name="m"><ssc:BaseUnit m="1"/></ssc:Unit>'
         '<ssc:Unit name="s"><ssc:BaseUnit s="1"/></ssc:Unit></ssd:Units>')


def test_units_convert_before_the_linear_transformation(fmus, tmp_path, capsys):
    """b1.y is in km, b2.u in m: u = 2 * (1000 y1) (SSP: units first, then factor)."""
    def scene(folder, unit, attributes=""):
        return write_scene(folder, system(
            block("b1", inside=connectors(("y", "output", "Real", "km")))
            + block("b2", inside=connectors(("u", "input", "Real", unit))),
            connection("b1", "y", "b2", "u", '<ssc:LinearTransformation factor="2"/>',
                       attributes)), {"block.fmu": fmus["state"]}, units=UNITS)

    result = dsim.simulate(scene(tmp_path / "m", "m"))
    b1 = lag(50, 1.0, lambda n, y: 0.0)
    b2 = lag(50, 1.0, lambda n, y: GAIN * 2.0 * (1000.0 * b1[n]))
    assert np.max(np.abs(result["b2.y"] - b2)) < 1e-12 * np.max(np.abs(b2))
    plain = dsim.simulate(scene(tmp_path / "plain", "m", ' suppressUnitConversion="true"'))
    b2 = lag(50, 1.0, lambda n, y: GAIN * 2.0 * b1[n])  # the factor alone
    assert np.max(np.abs(plain["b2.y"] - b2)) < 1e-12 * np.max(np.abs(b2))
    assert main(["run", str(scene(tmp_path / "s", "s")), "--quiet",
                 "--out", str(tmp_path / "o.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].endswith(
        "cannot connect 'km' (m) and 's' (s) are not the same dimension")


def test_parameter_bindings_at_every_level(fmus, tmp_path):
    """The root's binding overrides the component's (gain); a prefixed binding targets
    one element (tau of b2); a parameter mapping renames and scales (K -> gain of b2)."""
    mapping = ('<ssm:ParameterMapping version="1.0"><ssm:MappingEntry source="K" '
               'target="gain"><ssc:LinearTransformation factor="0.5"/></ssm:MappingEntry>'
               "</ssm:ParameterMapping>")
    files = {"resources/b2.ssv": '<?xml version="1.0"?>\n' + values(K=3.0).replace(
                 "<ssv:ParameterSet", '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/'
                 'SSP1/SystemStructureParameterValues"'),
             "resources/b2.ssm": '<?xml version="1.0"?>\n' + mapping.replace(
                 "<ssm:ParameterMapping", '<ssm:ParameterMapping xmlns:ssm="http://ssp-'
                 'standard.org/SSP1/SystemStructureParameterMapping" xmlns:ssc="http://ssp-'
                 'standard.org/SSP1/SystemStructureCommon"'),
             "resources/heavy.ssv": '<?xml version="1.0"?>\n' + values(**{"b1.gain": 4.0})
             .replace('name="set"', 'name="heavy" xmlns:ssv="http://ssp-standard.org/SSP1/'
                      'SystemStructureParameterValues"')}
    b1 = block("b1", inside="<ssd:ParameterBindings>" + binding(gain=3.0, u=1.0)
               + "</ssd:ParameterBindings>")
    b2 = block("b2", inside='<ssd:ParameterBindings><ssd:ParameterBinding source="resources/'
               'b2.ssv"><ssd:ParameterMapping source="resources/b2.ssm"/></ssd:'
               "ParameterBinding>" + binding(u=1.0) + "</ssd:ParameterBindings>")
    root = ("<ssd:ParameterBindings>" + binding(**{"b1.gain": 2.0}) + binding("b2.", tau=0.05)
            + "</ssd:ParameterBindings>")
    folder = write_scene(tmp_path, system(b1 + b2, inside=root), {"block.fmu": fmus["state"]},
                         files=files)
    scene = dsim.load_scene(folder)
    assert scene.component("b1").parameters["gain"] == ("Real", 2.0)
    assert scene.component("b2").parameters["gain"] == ("Real", 1.5)
    assert scene.component("b2").parameters["tau"] == ("Real", 0.05)
    result = dsim.simulate(folder)
    assert np.max(np.abs(result["b1.y"] - lag(50, 1.0, lambda n, y: 2.0))) < 1e-14
    decay = math.exp(-H / 0.05)
    expected = [1.0]
    for _ in range(50):
        expected.append(1.5 + (expected[-1] - 1.5) * decay)
    assert np.max(np.abs(result["b2.y"] - expected)) < 1e-14
    # a parameter set of the scene on top of everything, by its name
    heavy = dsim.simulate(folder, parameter_set="heavy")
    assert np.max(np.abs(heavy["b1.y"] - lag(50, 1.0, lambda n, y: 4.0))) < 1e-14
    with pytest.raises(dsim.InputError, match="no such .ssv file or ParameterSet in the "
                                              "scene .it has: heavy, set"):
        dsim.prepare(folder, parameter_set="light")


def test_system_connectors_carry_values_across_levels(fmus, tmp_path):
    """A ring through a nested system: b1.y -> sub.in -> sub.b2.u, sub.b2.y -> sub.out
    -> b1.u; one connection written end first (its connectors' kinds say the way)."""
    sub = system(block("b2", inside=connectors(("u", "input", "Real", None),
                                                ("y", "output", "Real", None))),
                 connection(None, "in", "b2", "u") + connection(None, "out", "b2", "y"),
                 inside=connectors(("in", "input", "Real", None),
                                   ("out", "output", "Real", None)), name="sub")
    b1 = block("b1", inside=connectors(("u", "input", "Real", None),
                                       ("y", "output", "Real", None)))
    folder = write_scene(tmp_path, system(
        b1 + sub, connection("b1", "y", "sub", "in") + connection("sub", "out", "b1", "u")),
        {"block.fmu": fmus["state"]})
    scene = dsim.load_scene(folder)
    assert sorted((c.start, c.end) for c in scene.connections) == [
        (("b1", "y"), ("sub.b2", "u")), (("sub.b2", "y"), ("b1", "u"))]
    from benchmarks.causal_benchmark import recurrence
    result = dsim.simulate(folder)
    ring = recurrence(2, 50, False)
    assert np.max(np.abs(result["b1.y"][1:] - ring[:, 0])) < 1e-15
    assert np.max(np.abs(result["sub.b2.y"][1:] - ring[:, 1])) < 1e-15


def test_connections_are_applied_at_initialization(fmus, built, tmp_path):
    """A SpringMass position (computed in initialization mode from x0 = 0.7) feeds the
    block's fixed parameter y0: set once, before the first step."""
    shutil.copy(built["fmus"] / "SpringMass.fmu", tmp_path / "SpringMass.fmu")
    mass = block("mass", "resources/SpringMass.fmu", "<ssd:ParameterBindings>"
                 + binding(**{"x0[1]": 0.7, "k_ground[1]": 1.0}) + "</ssd:ParameterBindings>")
    folder = write_scene(tmp_path / "scene", system(
        mass + block("b1"), connection("mass", "x[1]", "b1", "y0")),
        {"block.fmu": fmus["state"], "SpringMass.fmu": tmp_path / "SpringMass.fmu"})
    result = dsim.simulate(folder)
    assert result["b1.y"][0] == 0.7
    assert np.max(np.abs(result["b1.y"] - lag(50, 0.7, lambda n, y: 0.0))) < 1e-15


def test_start_values_follow_fmis_rules(fmus, tmp_path, capsys):
    folder = write_scene(tmp_path, system(block("b1", inside="<ssd:ParameterBindings>"
                                                + binding(y=1.0, u=2.0)
                                                + "</ssd:ParameterBindings>")),
                         {"block.fmu": fmus["state"]})
    assert main(["run", str(folder), "--quiet", "--out", str(tmp_path / "o.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    assert "'b1.y' is a continuous output with initial=calculated: FMI 2.0 lets no master " \
           "set it" in lines[0]


def test_a_scene_without_default_experiment_says_what_it_runs(fmus, tmp_path, capsys):
    folder = write_scene(tmp_path, system(block("b1")), {"block.fmu": fmus["state"]},
                         experiment=False)
    result = dsim.simulate(folder, step=0.01)
    assert result.ok and result.time == 1.0
    assert result.warnings[0].endswith("no DefaultExperiment: the run goes from 0 to 1 s "
                                       "(dsim's default; --stop sets the stop time)")
    assert main(["info", str(folder)]) == 0
    assert "no DefaultExperiment: dsim's default span" in capsys.readouterr().out
    assert dsim.simulate(folder, step=0.01, stop=0.5).warnings == []


def test_a_fixed_step_fmu_refuses_a_shortened_last_step(fmus, tmp_path, capsys):
    folder = write_scene(tmp_path, system(block("b1", "resources/block_fixed.fmu")),
                         {"block_fixed.fmu": fmus["fixed_step"]}, stop=0.0105)
    assert main(["run", str(folder), "--quiet", "--out", str(tmp_path / "o.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "needs a fixed communication step" in lines[0]
    assert dsim.simulate(folder, stop=0.01).ok


@pytest.mark.parametrize("kind, expected", [
    ("fmi1me", "block.fmu: an FMI 1.0 ModelExchange FMU: dsim runs FMI 1.0 co-simulation "
               "and FMI 2.0 and 3.0 co-simulation and Model Exchange FMUs"),
    ("clock", "block.fmu: variable 'tick' is a Clock: dsim does not run clocked FMI 3.0 "
              "FMUs (clocks and clocked partitions)"),
    ("fmi3", "block.fmu: no binary for this platform (binaries/x86_64-linux/b.so missing; "
             "the FMU has no binaries)"),
    ("me", "block.fmu: no binary for this platform (binaries/linux64/b.so missing; the FMU "
           "has no binaries)")])
def test_fmus_dsim_does_not_run_are_one_line(tmp_path, capsys, kind, expected):
    """What dsim refuses of an FMU's kind is one line: FMI 1.0 Model Exchange, clocks;
    FMI 3.0 and Model Exchange FMUs are run (these fakes are refused for their missing
    binary, after the kind was accepted)."""
    description = {
        "fmi1me": '<?xml version="1.0"?><fmiModelDescription fmiVersion="1.0" '
                  'modelName="b" modelIdentifier="b" guid="{x}" numberOfContinuousStates="0" '
                  'numberOfEventIndicators="0"><ModelVariables/></fmiModelDescription>',
        "clock": '<?xml version="1.0"?><fmiModelDescription fmiVersion="3.0" modelName="b" '
                 'instantiationToken="{x}"><CoSimulation modelIdentifier="b"/><ModelVariables>'
                 '<Float64 name="time" valueReference="0" causality="independent" '
                 'variability="continuous"/><Clock name="tick" valueReference="1" '
                 'causality="input" variability="discrete" intervalVariability="triggered"/>'
                 '</ModelVariables><ModelStructure/></fmiModelDescription>',
        "fmi3": '<?xml version="1.0"?><fmiModelDescription fmiVersion="3.0" modelName="b" '
                'instantiationToken="{x}"><CoSimulation modelIdentifier="b"/><ModelVariables>'
                '<Float64 name="time" valueReference="0" causality="independent" '
                'variability="continuous"/></ModelVariables><ModelStructure/>'
                "</fmiModelDescription>",
        "me": '<?xml version="1.0"?><fmiModelDescription fmiVersion="2.0" modelName="b" '
              'guid="{x}"><ModelExchange modelIdentifier="b"/><ModelVariables>'
              '<ScalarVariable name="x" valueReference="0" causality="output" '
              'variability="continuous" initial="calculated"><Real/></ScalarVariable>'
              "</ModelVariables><ModelStructure><Outputs><Unknown index=\"1\"/></Outputs>"
              "</ModelStructure></fmiModelDescription>"}[kind]
    fmu = fake_fmu(tmp_path / "block.fmu", description)
    folder = write_scene(tmp_path / "scene", system(block("b1")), {"block.fmu": fmu})
    assert main(["run", str(folder), "--quiet", "--out", str(tmp_path / "o.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].endswith(expected), lines


def test_an_fmu_without_state_saving_takes_part_causally_in_a_glued_scene(
        fmus, built, tmp_path):
    """spring_mass_linear, and a block that cannot save its state fed by left.x[1]: the
    gluing iterates the masses; the block takes one doStep per step, never saved."""
    with zipfile.ZipFile(built["ssp"] / "spring_mass_linear.ssp") as archive:
        archive.extractall(tmp_path / "scene")
    shutil.copy(fmus["nostate"], tmp_path / "scene" / "resources" / "block.fmu")
    ssd = tmp_path / "scene" / "SystemStructure.ssd"
    text = ssd.read_text().replace(
        "</ssd:Elements>", block("b1") + "</ssd:Elements><ssd:Connections>"
        + connection("left", "x[1]", "b1", "u") + "</ssd:Connections>")
    ssd.write_text(text)
    result = dsim.simulate(tmp_path / "scene", stop=0.5)
    assert result.ok and result.statistics["coupling"] == "iterative"
    block_stats = result.statistics["components"]["b1"]
    assert block_stats["state_saves"] == 0 and block_stats["do_steps"] == 50
    x1 = result["left.x[1]"]
    expected = [1.0]
    decay = math.exp(-0.01 / TAU)  # the scene's step is 0.01 s
    for n in range(50):
        expected.append(GAIN * x1[n] + (expected[-1] - GAIN * x1[n]) * decay)
    assert np.max(np.abs(result["b1.y"] - expected)) < 1e-15
