"""The macro step OMSimulator and the Open Simulation Platform write into an SSD is
the run's step when dsim's own settings give none (master/reading/ssp_tools.py), with the
precedence --step > glue:Master > those annotations > dsim's default; dsim info and
validate say where the step came from."""
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.scene_files import component, scene_folder, ssd

OMS = ('<ssd:Annotations><ssc:Annotation type="org.openmodelica">'
       '<oms:Annotations xmlns:oms="https://raw.githubusercontent.com/OpenModelica/OMSimulator/'
       'master/schema/oms.xsd"><oms:SimulationInformation>'
       '<oms:FixedStepMaster description="oms-ma" stepSize="{step}" absoluteTolerance="1e-4" '
       'relativeTolerance="1e-4"/></oms:SimulationInformation></oms:Annotations>'
       "</ssc:Annotation></ssd:Annotations>")
OSP = ('<ssc:Annotation type="com.opensimulationplatform">'
       '<osp:Algorithm xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations">'
       '<osp:FixedStepAlgorithm baseStepSize="{step}"/></osp:Algorithm></ssc:Annotation>')


CSE = ('<ssd:Annotations><ssc:Annotation type="org.open-simulation-platform">'
       '<osp:SimulationInformation xmlns:osp="http://opensimulationplatform.com/SSP/'
       'OSPAnnotations"><osp:FixedStepMaster description="x" stepSize="{step}"/>'
       "</osp:SimulationInformation></ssc:Annotation></ssd:Annotations>")


def scene(folder, fmu, oms=None, osp=None, master="", cse=None):
    """A block scene with the tools' step annotations (None: without)."""
    text = ssd("tools", [component("b1", "resources/block.fmu", outputs=["y"])], stop=0.1,
               master=master)
    if cse is not None:  # on the root system, as libcosim's predecessor read it
        text = text.replace("</ssd:Elements></ssd:System>",
                            "</ssd:Elements>" + CSE.format(step=cse) + "</ssd:System>")
    if oms is not None:  # on the root system, after its elements, as OMSimulator writes it
        text = text.replace("</ssd:Elements></ssd:System>",
                            "</ssd:Elements>" + OMS.format(step=oms) + "</ssd:System>")
    if osp is not None:  # on the DefaultExperiment, beside dsim's own
        text = text.replace('<ssc:Annotation type="org.dsim.master">',
                            OSP.format(step=osp) + '<ssc:Annotation type="org.dsim.master">')
    return scene_folder(folder, text, {"block.fmu": fmu})


@pytest.mark.parametrize("oms, osp, master, step, source", [
    ("0.02", None, "", 0.02, "OMSimulator annotation (FixedStepMaster stepSize)"),
    (None, "0.025", "", 0.025, "Open Simulation Platform annotation (FixedStepAlgorithm "
                               "baseStepSize)"),
    ("0.02", None, 'step="0.005"', 0.005, "glue:Master"),
    (None, None, "", 1e-3, "dsim's default"),
])
def test_the_step_comes_from_the_scene_in_order(block_fmus, tmp_path, capsys, oms, osp,
                                                 master, step, source):
    folder = scene(tmp_path / "s", block_fmus["state"], oms, osp, master)
    loaded = dsim.load_scene(folder)
    assert loaded.master.step == step and loaded.step_from == source
    assert main(["info", str(folder)]) == 0
    assert f"step {step:g} s (from {source})" in capsys.readouterr().out
    assert main(["validate", str(folder)]) == 0
    assert f"in steps of {step:g} s (from {source})" in capsys.readouterr().out
    result = dsim.simulate(folder, handle_signals=False)
    assert result.status == "completed" and result.steps == round(0.1 / step)


def test_the_step_option_wins_over_every_annotation(block_fmus, tmp_path, capsys):
    folder = scene(tmp_path / "s", block_fmus["state"], "0.02", "0.025", 'step="0.005"')
    assert main(["validate", str(folder), "--step", "0.01"]) == 0
    assert "in steps of 0.01 s (from the step setting (--step))" in capsys.readouterr().out
    assert dsim.simulate(folder, step=0.01, handle_signals=False).steps == 10


@pytest.mark.parametrize("bad", ["abc", "-1", "0", "inf"])
def test_a_bad_tool_step_is_one_line_naming_the_element(block_fmus, tmp_path, capsys, bad):
    folder = scene(tmp_path / "s", block_fmus["state"], oms=bad)
    assert main(["validate", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "OMSimulator annotation FixedStepMaster: stepSize" in lines[0]
    assert str(folder) in lines[0] and "line" in lines[0]


def test_the_step_of_libcosims_predecessor_is_read(block_fmus, tmp_path):
    folder = scene(tmp_path / "s", block_fmus["state"], cse="0.05")
    loaded = dsim.load_scene(folder)
    assert loaded.master.step == 0.05
    assert loaded.step_from == "Open Simulation Platform annotation (FixedStepMaster stepSize)"
