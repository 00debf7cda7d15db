"""SSP files as more tools write them: a scene without FMU components, .ssv
enumeration values given as item names, startElement="" inside a nested system,
Dymola-style connectors that name nothing, Integer/Real mismatches and an element
order that changes nothing: each read as the tool meant it, with a warning where it
breaks a rule (refused with --strict).  Every archive is built here."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dsim
from dsim.master.tools.cli import main
from tests.support.scene_files import component, pack, scene_folder, ssd
from tests.support.scenes import EMPTY_SSD

# --- a scene without FMU components --------------------------------------------------

@pytest.mark.parametrize("coupling", ["causal", "explicit", "iterative", "strong"])
def test_a_scene_without_components_runs_to_its_time_column(tmp_path, capsys, coupling):
    """Only system connectors and a parameter set (a parameter setup exported alone):
    validate says why in a warning, a run writes the time column and exits 0, --strict
    refuses it in one line."""
    folder = tmp_path / "setup"
    folder.mkdir()
    (folder / "SystemStructure.ssd").write_text(EMPTY_SSD)
    assert main(["validate", str(folder)]) == 0
    assert "has no FMU component" in capsys.readouterr().err
    out = tmp_path / "out.csv"
    assert main(["run", str(folder), "--out", str(out), "--coupling", coupling,
                 "--step", "0.1", "--quiet"]) == 0
    lines = out.read_text().split()
    assert lines[0] == "time"
    np.testing.assert_allclose([float(x) for x in lines[1:]], 0.1 * np.arange(6), atol=1e-15)
    result = dsim.simulate(folder, coupling=coupling, step=0.1)
    assert result.ok and len(result["time"]) == 6
    assert any("has no FMU component" in w for w in result.statistics["warnings"])
    capsys.readouterr()
    for command in (["validate"], ["run", "--out", str(tmp_path / "strict.csv")]):
        assert main([command[0], str(folder), "--strict", *command[1:]]) == 2
        errors = capsys.readouterr().err.strip().splitlines()
        assert len(errors) == 1 and "has no FMU component" in errors[0]


# --- .ssv enumeration values given as item names (SSP 1.0) ---------------------------

def _ssv(values: dict) -> str:
    """An .ssv of Enumeration parameters (``name: value text``)."""
    parameters = "".join(f'<ssv:Parameter name="{k}"><ssv:Enumeration value="{v}"/>'
                         "</ssv:Parameter>" for k, v in values.items())
    return ('<?xml version="1.0" encoding="UTF-8"?><ssv:ParameterSet version="1.0" '
            'name="set" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">'
            f"<ssv:Parameters>{parameters}</ssv:Parameters></ssv:ParameterSet>")


def _enumeration_scene(folder: Path, fmu: Path, value: str) -> Path:
    text = ssd("enum", [component("a", "resources/ender.fmu", {"F": 2.0},
                                  outputs=("P.u_x",))], stop=0.5, master='step="0.1"')
    text = text.replace("<ssd:ParameterBinding>", '<ssd:ParameterBinding source='
                        '"resources/set.ssv"/><ssd:ParameterBinding>')
    folder = scene_folder(folder, text, {"ender.fmu": fmu})
    (folder / "resources" / "set.ssv").write_text(_ssv({"direction": value}))
    return folder


@pytest.mark.parametrize("value, sign", [("Pull", -1.0), ("Push", 1.0), ("2", -1.0)])
def test_an_enumeration_value_named_by_its_item_is_that_items_value(ender, tmp_path, value,
                                                                   sign):
    """<ssv:Enumeration value="Pull"/> sets the item Pull (2) of the FMU's type: the mass
    is pulled, x = -t^2; an integer is still read as the item's value."""
    result = dsim.simulate(_enumeration_scene(tmp_path / "scene", ender, value))
    assert result.ok
    np.testing.assert_allclose(result["a.P.u_x"], sign * result["time"] ** 2, atol=1e-12)


def test_an_enumeration_name_that_is_no_item_is_refused_in_one_line(ender, tmp_path, capsys):
    folder = _enumeration_scene(tmp_path / "scene", ender, "Sideways")
    assert main(["validate", str(folder)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    assert "parameter 'direction' = 'Sideways' is no item of 'a.direction' (its items: " \
        "Push, Pull)" in lines[0]


# --- startElement="" inside a nested system ------------------------------------------

def test_an_empty_start_element_in_a_nested_system_is_that_system(ender, tmp_path):
    """b (pushed by 2 N: its acceleration is 2 m/s^2) feeds the nested system's input
    connector sub.u; inside sub, startElement="" (as OMSimulator writes) is sub itself,
    carried on to a's port force: a, unpushed otherwise, moves as x = t^2."""
    b = component("b", "resources/ender.fmu", {"F": 2.0}, outputs=("P.a_x",))
    a = component("a", "resources/ender.fmu", outputs=("P.u_x",), inputs=("P.f_x",))
    sub = ('<ssd:System name="sub"><ssd:Connectors><ssd:Connector name="u" kind="input">'
           f"<ssc:Real/></ssd:Connector></ssd:Connectors><ssd:Elements>{a}</ssd:Elements>"
           '<ssd:Connections><ssd:Connection startElement="" startConnector="u" '
           'endElement="a" endConnector="P.f_x"/></ssd:Connections></ssd:System>')
    text = ssd("nested", [b, sub], [("b", "P.a_x", "sub", "u")], stop=0.5,
               master='step="0.1"')
    result = dsim.simulate(scene_folder(tmp_path / "scene", text, {"ender.fmu": ender}))
    assert result.ok
    np.testing.assert_allclose(result["sub.a.P.u_x"], result["time"] ** 2, atol=1e-12)


# --- Dymola-style connectors that name nothing ---------------------------------------

DYMOLA_CONNECTORS = ('<ssd:Connector name="_x_start" kind="parameter"><ssc:Real/>'
                     '</ssd:Connector><ssd:Connector name="fmi_StartTime" kind="parameter">'
                     '<ssc:Real/></ssd:Connector><ssd:Connector name="_v_start" '
                     'kind="parameter"><ssc:Real/></ssd:Connector><ssd:Connector '
                     'name="fmi_StopTime" kind="parameter"><ssc:Real/></ssd:Connector>')


def _dymola_scene(folder: Path, fmu: Path, connect_missing: bool = False) -> Path:
    """Two enders, each declaring four connectors its FMU does not have (as Dymola
    writes); b's port force fed by a's acceleration (and, ``connect_missing``, a's
    _x_start fed into b's _v_start, a connection through connectors that name nothing)."""
    parts = [component("a", "resources/ender.fmu", {"F": 2.0}, outputs=("P.a_x",)),
             component("b", "resources/ender.fmu", outputs=("P.u_x",), inputs=("P.f_x",))]
    parts = [p.replace("<ssd:Connectors>", "<ssd:Connectors>" + DYMOLA_CONNECTORS)
             for p in parts]
    links = [("a", "P.a_x", "b", "P.f_x")]
    if connect_missing:
        links.append(("a", "_x_start", "b", "_v_start"))
    text = ssd("dymola", parts, links, stop=0.5, master='step="0.1"')
    return scene_folder(folder, text, {"ender.fmu": fmu})


def test_unconnected_connectors_that_name_nothing_are_dropped_with_a_warning(
        ender, tmp_path, capsys):
    folder = _dymola_scene(tmp_path / "scene", ender)
    assert main(["validate", str(folder)]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "dropped" in line]
    assert len(warned) == 2  # one per component
    assert "4 connector(s) name no variable of ender.fmu and are connected to nothing: " \
        "dropped (_x_start, fmi_StartTime, _v_start, ...)" in warned[0]
    result = dsim.simulate(folder)
    assert result.ok  # b pushed by a's 2 m/s^2 from the start: x = t^2
    np.testing.assert_allclose(result["b.P.u_x"], result["time"] ** 2, atol=1e-12)
    assert main(["validate", "--strict", str(folder)]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 2 and all("refused with --strict" in e for e in errors)


def test_a_connection_through_a_connector_that_names_nothing_is_one_error(ender, tmp_path,
                                                                          capsys):
    folder = _dymola_scene(tmp_path / "scene", ender, connect_missing=True)
    assert main(["validate", str(folder)]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines()
              if line.startswith("dsim: error")]
    assert len(errors) == 1 and "'a' has no variable '_x_start'" in errors[0]


# --- Integer and Real ----------------------------------------------------------------

def _counting_scene(folder: Path, fmu: Path, declared: str = "Real",
                    backwards: bool = False) -> Path:
    """Block b1's Integer output count (the steps it took) declared ``declared`` and fed
    into block b2's Real input u (``backwards``: b2's Real y into b1's Integer extra)."""
    b1 = component("b1", "resources/block.fmu").replace(
        'source="resources/block.fmu">', 'source="resources/block.fmu"><ssd:Connectors>'
        f'<ssd:Connector name="count" kind="output"><ssc:{declared}/></ssd:Connector>'
        "</ssd:Connectors>")
    b2 = component("b2", "resources/block.fmu", {"y0": 0.0}, outputs=("y",))
    links = [("b2", "y", "b1", "extra")] if backwards else [("b1", "count", "b2", "u")]
    text = ssd("counting", [b1, b2], links, stop=0.5, master='step="0.1"')
    return scene_folder(folder, text, {"block.fmu": fmu})


def test_an_integer_output_feeds_a_real_input_exactly_with_warnings(block_fmus, tmp_path,
                                                                    capsys):
    """count declared ssc:Real (it is an Integer) feeds b2.u: both are warnings, the value
    is carried exactly: b2 lags behind the count it sees at each step's start,
    y(n+1) = 0.9 n + (y(n) - 0.9 n) exp(-h / 0.1).  A Real into an Integer stays refused."""
    folder = _counting_scene(tmp_path / "scene", block_fmus["state"])
    assert main(["validate", str(folder)]) == 0
    err = capsys.readouterr().err
    assert "connector 'count' is declared Real, but the FMU's variable is Integer: read as " \
        "Integer" in err
    assert "connects an Integer 'b1.count' to a Real 'b2.u': carried as a Real (exact)" in err
    result = dsim.simulate(folder)
    assert result.ok
    expected = [0.0]
    for n in range(5):
        expected.append(0.9 * n + (expected[-1] - 0.9 * n) * np.exp(-0.1 / 0.1))
    np.testing.assert_allclose(result["b2.y"], expected, rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(result["b1.count"], np.arange(6))
    assert main(["validate", "--strict", str(folder)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 2
    # a Real into an Integer would be rounded: still refused, one line
    folder = _counting_scene(tmp_path / "backwards", block_fmus["state"], "Integer", True)
    assert main(["validate", str(folder)]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 1 and "connects a Real 'b2.y' to a Integer 'b1.extra'" in errors[0]


# --- an element order that changes nothing -------------------------------------------

def test_annotations_before_connectors_are_a_warning(ender, tmp_path, capsys):
    """<ssd:Annotations> before <ssd:Connectors> in a component (OMSimulator accepts it):
    read as if in order, with a warning; --strict refuses it."""
    part = component("a", "resources/ender.fmu", {"F": 2.0}, outputs=("P.u_x",)).replace(
        'source="resources/ender.fmu">', 'source="resources/ender.fmu"><ssd:Annotations>'
        '<ssc:Annotation type="com.example.tool"><note/></ssc:Annotation></ssd:Annotations>')
    text = ssd("order", [part], stop=0.3, master='step="0.1"')
    folder = scene_folder(tmp_path / "scene", text, {"ender.fmu": ender})
    assert main(["validate", str(folder)]) == 0
    assert "elements out of the order SSP 1.0 gives" in capsys.readouterr().err
    result = dsim.simulate(folder)
    np.testing.assert_allclose(result["a.P.u_x"], result["time"] ** 2, atol=1e-12)
    assert main(["validate", "--strict", str(folder)]) == 2


def _binding(values: dict) -> str:
    """One ssd:ParameterBindings of an inline parameter set of Real ``values``."""
    parameters = "".join(f'<ssv:Parameter name="{name}"><ssv:Real value="{value!r}"/>'
                         "</ssv:Parameter>" for name, value in values.items())
    return ("<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
            f'<ssv:ParameterSet version="1.0" name="set"><ssv:Parameters>{parameters}'
            "</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>"
            "</ssd:ParameterBinding></ssd:ParameterBindings>")


def test_an_element_repeated_where_ssp_allows_one_is_merged_in_order(ender, tmp_path,
                                                                      capsys):
    """As OMSimulator's importStartValues1 writes a system: its Annotations before its
    Connectors, and two ssd:ParameterBindings (SSP 1.0 allows one): read with one
    warning, the bindings merged in document order (the second's F = 2 N over the
    first's 8 N: x = t^2 on 1 kg; the first's m = 1 kg kept); --strict refuses it.  It
    was refused as not valid SSP 1.0."""
    part = component("a", "resources/ender.fmu", outputs=("P.u_x",))
    text = ssd("repeated", [part], stop=0.3, master='step="0.1"').replace(
        '<ssd:System name="root">',
        '<ssd:System name="root"><ssd:Annotations><ssc:Annotation type="org.openmodelica">'
        "<note/></ssc:Annotation></ssd:Annotations><ssd:Connectors><ssd:Connector "
        'name="C1" kind="input"><ssc:Real/></ssd:Connector></ssd:Connectors>'
        + _binding({"a.m": 1.0, "a.F": 8.0}) + _binding({"a.F": 2.0}))
    archive = pack(scene_folder(tmp_path / "scene", text, {"ender.fmu": ender}),
                   tmp_path / "repeated.ssp")
    assert main(["validate", str(archive)]) == 0
    warnings = capsys.readouterr().err.strip().splitlines()
    assert len(warnings) == 1, warnings
    assert "ssd:ParameterBindings 2 times in system 'root'" in warnings[0]
    assert "merged in order" in warnings[0]
    result = dsim.simulate(archive)
    assert result.ok, result.statistics["message"]
    np.testing.assert_allclose(result["a.P.u_x"], result["time"] ** 2, atol=1e-12)
    assert main(["validate", "--strict", str(archive)]) == 2
