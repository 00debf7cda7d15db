"""XML from an untrusted scene is parsed with no entity resolved, no DTD loaded and
nothing fetched (reading/small_files.py: untrusted_xml_parser): an SSD that declares an
external entity naming a file on the machine (XXE), or an internal one, is refused in one
line, and the file's content reaches nothing dsim reports.  With lxml's default parser the
same SSD ended in a traceback from the schema check."""
import zipfile

import pytest

from dsim.master.errors import InputError
from dsim.master.reading.parameter_input import given_parameters
from dsim.master.reading.ssp import read_scene

SECRET = "TOPSECRET-7f3a"


def _doctype(entities: str) -> str:
    return f"<!DOCTYPE ssd:SystemStructureDescription [{entities}]>\n"


@pytest.mark.parametrize("entity", ["external", "internal"])
def test_an_ssd_with_entities_is_refused_in_one_line_and_no_file_is_read(built, tmp_path,
                                                                          entity):
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET)
    scene = tmp_path / "scene"
    zipfile.ZipFile(built["ssp"] / "spring_mass_linear.ssp").extractall(scene)
    ssd = scene / "SystemStructure.ssd"
    text = ssd.read_text()
    declared = (f'<!ENTITY e SYSTEM "file://{secret}">' if entity == "external"
                else f'<!ENTITY e "{SECRET}">')
    header, rest = text.split("\n", 1)
    rest = rest.replace('<ssd:System name="root">', '<ssd:System name="root">'
                        '<ssd:Annotations><ssc:Annotation type="org.example">&e;'
                        '</ssc:Annotation></ssd:Annotations>', 1)
    ssd.write_text(header + "\n" + _doctype(declared) + rest)
    with pytest.raises(InputError) as refused:
        read_scene(scene)
    message = str(refused.value)
    assert "\n" not in message and "malformed XML" in message and "DTD" in message, message
    assert SECRET not in message


def test_a_parameter_set_with_an_external_entity_is_refused(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("12.5")
    ssv = tmp_path / "set.ssv"
    ssv.write_text(
        "<?xml version='1.0' encoding='UTF-8'?>\n"
        + _doctype(f'<!ENTITY e SYSTEM "file://{secret}">').replace(
            "ssd:SystemStructureDescription", "ssv:ParameterSet") +
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
        ' version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="left.m">'
        '<ssv:Real value="&e;"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>')
    with pytest.raises(InputError) as refused:
        given_parameters([str(ssv)], [])
    assert "malformed XML" in str(refused.value) and "12.5" not in str(refused.value)
