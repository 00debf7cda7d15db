"""Where a component's FMU comes from: a source outside the scene is one line without
follow-on errors unless --allow-outside trusts its folder (and nothing beyond it: ../
escapes, links, absolute paths), and an FMU without a binary for this platform says
so before any complaint about its description."""
from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.scene_files import component, scene_folder, ssd

# --- FMUs outside the scene: refused in one line, or trusted with --allow-outside -----

def _outside_scene(root: Path, fmu: Path, source: str = "../../fmi2/ender.fmu",
                   glued: bool = False) -> Path:
    """root/fmi2/ender.fmu beside root/scenes/loader/ (a platform's loader test): a
    (source ``source``) pushed by 2 N feeds b (inside the scene) through a connection;
    ``glued``: a and b in a fixed joint as well."""
    (root / "fmi2").mkdir(parents=True, exist_ok=True)
    shutil.copy(fmu, root / "fmi2" / "ender.fmu")
    a = component("a", source, {"F": 2.0}, outputs=("P.u_x", "P.a_x"))
    b = component("b", "resources/ender.fmu", outputs=("P.u_x",), inputs=("P.f_x",))
    gluing = '<glue:Joint name="j" a="a.P" b="c.P" dofs="x" kind="fixed"/>' if glued else ""
    parts = [a, b] + ([component("c", "resources/ender.fmu")] if glued else [])
    text = ssd("loader", parts, [("a", "P.a_x", "b", "P.f_x")], gluing=gluing, stop=0.3,
               master='step="0.1"')
    # a value for a, bound at the root system: nothing more to say once a is refused
    text = text.replace('<ssd:System name="root">', '<ssd:System name="root">'
                        "<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
                        '<ssv:ParameterSet version="1.0" name="root"><ssv:Parameters>'
                        '<ssv:Parameter name="a.m"><ssv:Real value="1"/></ssv:Parameter>'
                        "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
                        "</ssd:ParameterBinding></ssd:ParameterBindings>")
    return scene_folder(root / "scenes" / "loader", text, {"ender.fmu": fmu})


@pytest.mark.parametrize("glued", [False, True])
def test_an_fmu_outside_the_scene_is_one_line_without_follow_on_errors(ender, tmp_path,
                                                                       capsys, glued):
    folder = _outside_scene(tmp_path, ender, glued=glued)
    for command in (["validate"], ["run", "--out", str(tmp_path / "out.csv")]):
        assert main([command[0], str(folder), *command[1:]]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1, lines
        assert "FMU source '../../fmi2/ender.fmu' is outside the scene (--allow-outside " \
            "DIR trusts a folder: docs/security.md)" in lines[0]
    assert not (tmp_path / "out.csv").exists()


def test_allow_outside_trusts_one_folder(ender, tmp_path, capsys):
    folder = _outside_scene(tmp_path, ender)
    trusted = str(tmp_path / "fmi2")
    assert main(["validate", str(folder), "--allow-outside", trusted]) == 0
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "--allow-outside", trusted, "--out", str(out),
                 "--quiet"]) == 0
    assert main(["info", str(folder), "--allow-outside", trusted]) == 0
    result = dsim.simulate(folder, allow_outside=trusted)
    np.testing.assert_allclose(result["a.P.u_x"], result["time"] ** 2, atol=1e-12)
    np.testing.assert_allclose(result["b.P.u_x"], result["time"] ** 2, atol=1e-12)
    # a folder that does not exist is one line
    capsys.readouterr()
    assert main(["validate", str(folder), "--allow-outside", str(tmp_path / "nowhere")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "no such folder" in lines[0]


def test_sweep_and_regress_take_allow_outside_as_run_does(ender, tmp_path, capsys):
    """dsim sweep and dsim regress refused --allow-outside (a usage error); now every
    point and every case trusts the folder as dsim run does (without it, the scene is
    refused in one line, exit 2, as by dsim run)."""
    folder = _outside_scene(tmp_path, ender)
    trusted = str(tmp_path / "fmi2")
    out = tmp_path / "sweep"
    assert main(["sweep", str(folder), "--step", "0.1,0.05", "--out", str(out)]) == 2
    assert "is outside the scene" in capsys.readouterr().err
    assert main(["sweep", str(folder), "--step", "0.1,0.05", "--out", str(out),
                 "--allow-outside", trusted, "--target-error", "1"]) == 0
    said = capsys.readouterr().out
    assert "2 points (2 completed)" in said and f"--allow-outside {trusted}" in said
    for point in ("point_001", "point_002"):
        time, x = np.loadtxt(out / f"{point}.csv", delimiter=",", skiprows=1,
                             usecols=(0, 1), unpack=True)
        np.testing.assert_allclose(x, time ** 2, atol=1e-12)
    scenes = folder.parent  # root/scenes: the loader scene, its baseline stored beside
    assert main(["regress", str(scenes), "--update", "--no-kernel-study",
                 "--allow-outside", trusted]) == 0
    assert main(["regress", str(scenes)]) == 1  # refused without the trust: an error
    assert "is outside the scene" in capsys.readouterr().err
    assert main(["regress", str(scenes), "--allow-outside", trusted]) == 0
    assert "loader: passed" in capsys.readouterr().err


@pytest.mark.parametrize("attack", ["dotdot", "symlink", "link_in_trusted", "absolute"])
def test_allow_outside_trusts_nothing_beyond_its_folder(ender, tmp_path, capsys, attack):
    """With --allow-outside fmi2: a ../ escape to another folder, a link in the scene to
    a file outside both, a link inside the trusted folder that leads out of it, and an
    absolute path are all refused (links resolved before the check); without the
    option, a link to the trusted folder's FMU is refused too."""
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(ender, other / "ender.fmu")
    source = {"dotdot": "../../other/ender.fmu", "symlink": "resources/link.fmu",
              "link_in_trusted": "../../fmi2/link.fmu",
              "absolute": str(other / "ender.fmu")}[attack]
    folder = _outside_scene(tmp_path, ender, source)
    (folder / "resources" / "link.fmu").symlink_to(other / "ender.fmu")
    (tmp_path / "fmi2" / "link.fmu").symlink_to(other / "ender.fmu")
    assert main(["validate", str(folder), "--allow-outside", str(tmp_path / "fmi2")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert ("is an absolute path" if attack == "absolute" else "is outside the scene and "
            "the folders --allow-outside trusts") in lines[0]
    # a link in the scene to the trusted folder's FMU: refused unless that folder is trusted
    (folder / "resources" / "trusted.fmu").symlink_to(tmp_path / "fmi2" / "ender.fmu")
    text = (folder / "SystemStructure.ssd").read_text().replace(source, "resources/trusted.fmu")
    (folder / "SystemStructure.ssd").write_text(text)
    assert main(["validate", str(folder)]) == 2
    capsys.readouterr()
    assert main(["validate", str(folder), "--allow-outside", str(tmp_path / "fmi2")]) == 0


# --- one error per cause, the most fundamental first ---------------------------------

def test_no_binary_for_this_platform_is_said_before_a_description_complaint(
        ender, tmp_path, capsys):
    """An FMU whose description names a unit it does not define (fmpy's check refuses
    it) and that has a library only for Windows: the one line says what no fix of the
    description would cure, no binary for this platform; its connection adds nothing."""
    broken = tmp_path / "windows.fmu"
    with zipfile.ZipFile(ender) as source, zipfile.ZipFile(broken, "w") as target:
        text = source.read("modelDescription.xml").decode().replace(
            'name="m" valueReference="0" causality="parameter" variability="fixed"><Real',
            'name="m" valueReference="0" causality="parameter" variability="fixed"><Real '
            'unit="kg"')
        assert 'unit="kg"' in text
        target.writestr("modelDescription.xml", text)
        target.writestr("binaries/win64/ender.dll", source.read("binaries/linux64/ender.so"))
    a = component("a", "resources/windows.fmu", outputs=("P.a_x",))
    b = component("b", "resources/ender.fmu", inputs=("P.f_x",))
    text = ssd("blocked", [a, b], [("a", "P.a_x", "b", "P.f_x")], stop=0.3)
    folder = scene_folder(tmp_path / "scene", text, {"ender.fmu": ender,
                                                      "windows.fmu": broken})
    assert main(["validate", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert "FMU windows.fmu: no binary for this platform (binaries/linux64/ender.so " \
        "missing; the FMU has win64)" in lines[0]
