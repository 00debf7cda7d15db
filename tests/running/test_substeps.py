"""A step per FMU: a component exchanged once per step takes N communication steps per
macro step, its inputs held (``--substeps COMPONENT=N``, ``--substeps auto`` from its
FMU's DefaultExperiment stepSize); the CSV keeps the macro grid.  The C oscillator
(tests/support/third_party/oscillator.c, m = k = 1, s0 = 1: x = cos t) integrates with the
trapezoidal rule over each step it is given, so four substeps make its error 16 times
smaller."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.scene_files import edited_archive
from tests.support.scenes import archive_scene

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")

#: the oscillator's position recorded, and s0 = 1 m bound
INSIDE = ('<ssd:Connectors><ssd:Connector name="s" kind="output"><ssc:Real/></ssd:Connector>'
          '</ssd:Connectors><ssd:ParameterBindings><ssd:ParameterBinding>'
          '<ssd:ParameterValues><ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/'
          'SystemStructureParameterValues" version="1.0" name="p"><ssv:Parameters>'
          '<ssv:Parameter name="s0"><ssv:Real value="1"/></ssv:Parameter></ssv:Parameters>'
          "</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>"
          "</ssd:ParameterBindings>")


@pytest.fixture(scope="module")
def oscillators(tmp_path_factory):
    """The C oscillator FMU, as built and with a DefaultExperiment stepSize of 0.025 s."""
    from tests.support.third_party.build import OSCILLATOR_VARIABLES, c_fmu

    folder = tmp_path_factory.mktemp("substeps")
    plain = c_fmu(folder, "oscillator", "oscillator.c", OSCILLATOR_VARIABLES)
    stepped = folder / "stepped.fmu"
    with zipfile.ZipFile(plain) as source, zipfile.ZipFile(stepped, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b"<ModelVariables>", b'<DefaultExperiment stepSize="0.025"/>'
                                    b"<ModelVariables>")
            target.writestr(item, data)
    return {"plain": plain, "stepped": stepped}


def lone(fmu: Path, path: Path, annotation: str = "") -> Path:
    """The oscillator alone over 10 s at a 0.1 s macro step; ``annotation``: the
    attributes of a glue:Substeps annotation on it (none when empty)."""
    return archive_scene(path, {"m": (fmu, "", INSIDE + substeps_annotation(annotation))},
                         stop=10.0, step=0.1)


def substeps_annotation(attributes: str) -> str:
    """A component's ssd:Annotations holding dsim's glue:Substeps with ``attributes``
    ("" : none)."""
    if not attributes:
        return ""
    return ('<ssd:Annotations><ssc:Annotation type="org.dsim.substeps">'
            f'<glue:Substeps xmlns:glue="urn:dsim:gluing:1" {attributes}/>'
            "</ssc:Annotation></ssd:Annotations>")


def error(result) -> float:
    return float(np.max(np.abs(result["m.s"] - np.cos(result["time"]))))


def test_four_substeps_make_the_trapezoidal_error_sixteen_times_smaller(oscillators, tmp_path):
    path = lone(oscillators["plain"], tmp_path / "lone.ssp")
    once = dsim.simulate(path)
    four = dsim.simulate(path, substeps={"m": 4})
    assert once.ok and four.ok
    assert np.array_equal(once["time"], four["time"]) and len(four["time"]) == 101
    print(f"one step: {error(once):.3g}, four substeps: {error(four):.3g}")
    assert 14 < error(once) / error(four) < 18
    steps = four.statistics["components"]["m"]["do_steps"]
    assert steps == 4 * once.statistics["components"]["m"]["do_steps"]
    assert four.statistics["substeps"] == {"m": 4} and once.statistics["substeps"] == {}


def test_auto_takes_the_fmus_default_experiment_step(oscillators, tmp_path, capsys):
    path = lone(oscillators["stepped"], tmp_path / "auto.ssp")
    out = tmp_path / "auto.csv"
    assert main(["run", str(path), "--substeps", "auto", "--out", str(out), "--quiet"]) == 0
    statistics = json.loads(out.with_suffix(".stats.json").read_text())
    assert statistics["substeps"] == {"m": 4}  # 0.1 s over 0.025 s
    given = dsim.simulate(path, substeps={"m": 4})
    auto = dsim.simulate(path, substeps="auto")
    assert np.array_equal(given["m.s"], auto["m.s"])
    # one component's count on top of auto
    assert dsim.simulate(path, substeps={"*": "auto", "m": 2}).statistics["substeps"] == {
        "m": 2}


@pytest.mark.parametrize("given, expected", [
    ("nope=2", "substeps: no component 'nope' (components: m)"),
    ("m=0", "substeps: 'm=0': give a whole number >= 1"),
    ("m=2.5", "substeps: 'm=2.5': give a whole number >= 1"),
    ("m", "--substeps m: give COMPONENT=N"),
])
def test_bad_substeps_are_one_line_and_exit_2(oscillators, tmp_path, capsys, given, expected):
    path = lone(oscillators["plain"], tmp_path / "bad.ssp")
    assert main(["run", str(path), "--substeps", given, "--out",
                 str(tmp_path / "bad.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], lines


def test_a_glued_component_takes_no_substeps(built, tmp_path, capsys):
    assert main(["run", str(built["ssp"] / "spring_mass_linear.ssp"), "--substeps", "left=2",
                 "--out", str(tmp_path / "glued.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "component 'left' is stepped with the others in a joint" \
        in lines[0], lines


def test_the_annotation_gives_what_the_command_line_gives(oscillators, tmp_path):
    plain = lone(oscillators["plain"], tmp_path / "plain.ssp")
    annotated = lone(oscillators["plain"], tmp_path / "annotated.ssp", 'count="4"')
    given = dsim.simulate(plain, substeps={"m": 4})
    read = dsim.simulate(annotated)
    assert read.statistics["substeps"] == {"m": 4}
    assert read.statistics["components"]["m"]["do_steps"] == 400
    assert np.array_equal(read["m.s"], given["m.s"])
    assert 3e-4 < error(read) < 5e-4  # against cos t: the four substeps' error, not one step's
    # the command line overrides the annotation for that component
    out = tmp_path / "override.csv"
    assert main(["run", str(annotated), "--substeps", "m=2", "--out", str(out), "--quiet"]) == 0
    statistics = json.loads(out.with_suffix(".stats.json").read_text())
    assert statistics["substeps"] == {"m": 2}
    assert statistics["components"]["m"]["do_steps"] == 200
    assert dsim.simulate(annotated, substeps={"m": 1}).statistics["substeps"] == {}
    # auto counts below the annotation: the FMU's 0.025 s step would give 4
    stepped = lone(oscillators["stepped"], tmp_path / "stepped.ssp", 'count="2"')
    assert dsim.simulate(stepped, substeps="auto").statistics["substeps"] == {"m": 2}


def test_a_bad_annotation_is_one_line_and_exit_2(oscillators, tmp_path):
    path = lone(oscillators["plain"], tmp_path / "bad_count.ssp", 'count="2.5"')
    out = tmp_path / "bad.csv"
    done = subprocess.run([sys.executable, "-m", "dsim", "run", str(path), "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert lines[0] == (f"dsim: error: {path} (SystemStructure.ssd line 5): glue:Substeps of "
                        "component 'm': count '2.5': give a whole number >= 1")
    assert not out.exists()  # nothing ran


@pytest.mark.parametrize("attributes, expected", [
    ('count="0"', "glue:Substeps of component 'm': count '0': give a whole number >= 1"),
    ('count="four"', "count 'four': give a whole number >= 1"),
    ('steps="4"', "glue:Substeps of component 'm': attribute 'count' missing"),
])
def test_bad_annotations(oscillators, tmp_path, capsys, attributes, expected):
    path = lone(oscillators["plain"], tmp_path / "bad.ssp", attributes)
    out = tmp_path / "bad.csv"
    assert main(["run", str(path), "--out", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and "bad.ssp" in lines[0], lines
    assert not out.exists()


def test_an_annotation_on_a_glued_component_is_refused(built, tmp_path, capsys):
    before = ('<ssd:ParameterBinding source="resources/left.ssv"/>\n'
              "        </ssd:ParameterBindings>")
    path = edited_archive(built["ssp"] / "spring_mass_linear.ssp", tmp_path / "glued.ssp",
                          "SystemStructure.ssd", before, before + substeps_annotation('count="2"'))
    assert main(["run", str(path), "--out", str(tmp_path / "glued.csv")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert "glued.ssp (SystemStructure.ssd line 13): glue:Substeps of component 'left': " \
           "the component is stepped with the others in a joint" in lines[0], lines
