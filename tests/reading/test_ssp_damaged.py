"""Damaged files of a scene are one line naming the file and exit 2, never a
traceback: an .ssv whose bytes are not its declared encoding (lxml raises OSError,
not a syntax error) and a component source too long to be a file name."""
import pytest

from dsim.master.tools.cli import main
from tests.support.scene_files import component, scene_folder, ssd

SSV = (b'<?xml version="1.0" encoding="UTF-8"?><ssv:ParameterSet xmlns:ssv='
       b'"http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" '
       b'name="p\xff\xfe"><ssv:Parameters/></ssv:ParameterSet>')


def bad_ssv_scene(folder, fmu):
    text = ssd("damaged", [component("b1", "resources/block.fmu")], stop=0.01)
    text = text.replace('source="resources/block.fmu">', 'source="resources/block.fmu">'
                        '<ssd:ParameterBindings><ssd:ParameterBinding source="resources/p.ssv"/>'
                        "</ssd:ParameterBindings>")
    folder = scene_folder(folder, text, {"block.fmu": fmu})
    (folder / "resources" / "p.ssv").write_bytes(SSV)
    return folder


def long_source_scene(folder, fmu):
    text = ssd("damaged", [component("b1", "resources/" + "x" * 1000 + ".fmu")], stop=0.01)
    return scene_folder(folder, text, {"block.fmu": fmu})


@pytest.mark.parametrize("command", ["validate", "run"])
@pytest.mark.parametrize("make, expected", [
    (bad_ssv_scene, "resources/p.ssv: cannot read: Error reading file"),
    (long_source_scene, "(1014 characters) cannot be a file name: File name too long"),
])
def test_a_damaged_file_is_one_line_and_exit_2(block_fmus, tmp_path, capsys, command, make,
                                               expected):
    folder = make(tmp_path / "scene", block_fmus["state"])
    extra = ["--out", str(tmp_path / "out.csv"), "--quiet"] if command == "run" else []
    assert main([command, str(folder), *extra]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"dsim: error: {folder}") and expected in lines[0]
    assert len(lines[0]) < 400  # the 1000 characters are not repeated
