"""Inputs from a table (``--input``, ``inputs=``; docs/inputs.md) and SSP table
components, on the C offset FMU of tests/support/third_party/offset.c (realOut = realIn
+ 1.234, realInEcho = realIn, intInEcho = intIn, all computed in its doStep): the row at
a communication point t + h shows the input fed at t, checked against hand-computed
values at every step."""
import hashlib
import shutil

import numpy as np
import pytest

import dsim
from tests.support.scene_files import component, scene_folder, ssd

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")

#: rows chosen so that every value at the steps of 0.1 s is exact in binary: linear
#: from 0 to 0.5 over 0 .. 0.25 s and on to 1 at 0.5 s, a jump to 2 at 0.5 s (two rows),
#: then 2 to 1.0 s, held after; intIn 1, 3 from 0.5 s, 4 at the jump, 5 from 1.0 s
TABLE = ("time,{p}realIn,{p}intIn\n"
         "0.25,0.5,1\n"
         "0.5,1,3\n"
         "0.5,2,4\n"
         "1,2,5\n")
# ... and the value before its first row (0.25 s) held: 0.5 at 0, 0.1 and 0.2 s
#: the input at each communication point 0, 0.1, ..., 1.0 s (FMPy's rules by hand):
#: held 0.5 before 0.25 s; 0.6, 0.8 at 0.3, 0.4 s (linear to 1 at 0.5); at 0.5 s the
#: jump's second row (2); 2 after
REAL = [0.5, 0.5, 0.5, 0.6, 0.8, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0]
#: intIn held from the last row at or before: 1 (first held), 4 at and after 0.5 s, 5
#: from 1.0 s
INTEGER = [1, 1, 1, 1, 1, 4, 4, 4, 4, 4, 5]


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    from tests.support.scenarios import offset_scenes

    folder = tmp_path_factory.mktemp("inputs")
    found = offset_scenes(folder)
    (folder / "in.csv").write_text(TABLE.format(p="slave uno."))
    road = ('<ssd:Component name="road" type="text/csv" source="resources/road.csv">'
            "<ssd:Connectors>"
            '<ssd:Connector name="realIn" kind="output"><ssc:Real/></ssd:Connector>'
            '<ssd:Connector name="intIn" kind="output"><ssc:Real/></ssd:Connector>'
            "</ssd:Connectors></ssd:Component>")
    table = scene_folder(folder / "table", ssd(
        "table", [component("slave uno", "resources/offset.fmu"), road],
        [("road", "realIn", "slave uno", "realIn"), ("road", "intIn", "slave uno", "intIn")],
        stop=1.1, master='step="0.1"'), {"offset.fmu": found["fmu"]})
    (table / "resources" / "road.csv").write_text(TABLE.format(p=""))
    found["table"] = table
    found["csv"] = folder / "in.csv"
    return found


def test_every_step_takes_the_table_at_its_start(scenes):
    result = dsim.simulate(scenes["single"], inputs=scenes["csv"], stop=1.1)
    assert result.status == "completed"
    # the row at 0 shows the start value; each later row the value fed at the point before
    echo = result["slave uno.realInEcho"]
    assert np.allclose(echo, [0.5] + REAL, rtol=0, atol=1e-15)  # (0.8 * 0.5 + 0.2 * 1)
    assert echo[[0, 1, 2, 3, 6, 11]].tolist() == [0.5, 0.5, 0.5, 0.5, 2.0, 2.0]  # held, jump
    assert result["slave uno.intInEcho"].tolist() == [1] + INTEGER
    assert np.allclose(result["slave uno.realOut"], np.array([0.5] + REAL) + 1.234,
                       rtol=0, atol=1e-15)
    # --input's columns are inputs, not recorded, and no coupling error is claimed
    assert not any(c.startswith("--input") for c in result.signals)
    assert not result.warnings
    # the statistics name the table and what each column fed
    assert result.statistics["inputs"] == {
        "table": str(scenes["csv"]), "fed": {"slave uno.realIn": "slave uno.realIn",
                                            "slave uno.intIn": "slave uno.intIn"}}


def test_a_mat_file_a_dataframe_and_a_structured_array_give_the_same_bytes(scenes, tmp_path):
    from scipy.io import savemat

    text = scenes["csv"].read_text().splitlines()
    rows = np.array([[float(x) for x in line.split(",")] for line in text[1:]])
    names = ["slave uno.realIn", "slave uno.intIn"]
    # dsim's own --mat layout, and one vector per signal under a struct ("slave uno" is
    # no MATLAB name: the layout with names is the one for such columns)
    savemat(tmp_path / "in.mat", {"time": rows[:, 0], "data": rows[:, 1:],
                                  "names": np.array(names, dtype=object)})
    structured = np.array([tuple(r) for r in rows], dtype=[("time", float)] + [
        (n, float) for n in names])
    given = {"mat": tmp_path / "in.mat", "structured": structured}
    pandas = pytest.importorskip("pandas")
    given["frame"] = pandas.DataFrame(rows[:, 1:], columns=names,
                                      index=pandas.Index(rows[:, 0], name="time"))
    outputs = {}
    for name, inputs in {"csv": scenes["csv"], **given}.items():
        out = tmp_path / f"{name}.csv"
        result = dsim.simulate(scenes["single"], inputs=inputs, stop=1.1, out=out)
        assert result.status == "completed", (name, result.message)
        outputs[name] = out.read_bytes()
    assert len(set(outputs.values())) == 1


def test_a_table_component_gives_the_numbers_of_the_same_table_as_input(scenes):
    from_input = dsim.simulate(scenes["single"], inputs=scenes["csv"], stop=1.1)
    component = dsim.simulate(scenes["table"])
    assert component.status == "completed" and not component.warnings
    for column in ("slave uno.realInEcho", "slave uno.realOut", "slave uno.intInEcho"):
        assert np.array_equal(component[column], from_input[column])
    # the table's own columns are recorded (OMSimulator records them too): its values at
    # each communication point
    assert np.allclose(component["road.realIn"], REAL + [2.0], rtol=0, atol=1e-15)
    assert component["road.intIn"].tolist() == INTEGER + [5]


def test_a_table_component_runs_the_same_on_the_isolated_backend(scenes, ray_local):
    here = dsim.simulate(scenes["table"])
    isolated = dsim.simulate(scenes["table"], backend="isolated")
    assert isolated.status == "completed", isolated.message
    assert all(np.array_equal(here[c], isolated[c]) for c in here.signals
               if here[c].dtype != object)


def test_without_inputs_the_run_is_unchanged(scenes, tmp_path):
    plan = dsim.prepare(scenes["chain"])
    assert all(s.table is None and s.table_inputs is None for s in plan.specs)
    out = tmp_path / "chain.csv"
    dsim.simulate(scenes["chain"], out=out)
    # the bytes of this run before input tables existed (the offset FMU adds decimals
    # in C: the same bytes on every machine)
    assert hashlib.md5(out.read_bytes()).hexdigest() == "501fa5d0afb4291c406642d3f85e319c"


def test_the_jump_at_the_first_row_and_a_point_a_hair_before_a_jump(scenes, tmp_path):
    # a jump at the table's very first time (FMPy's interpolate gives the first row's
    # value there; here the second's, as at any jump), and 0.3 = 3 * 0.1 reached as
    # 0.30000000000000004 by the run: at the jump
    path = tmp_path / "edge.csv"
    path.write_text("time,slave uno.realIn\n0,-1\n0,1\n0.3,1\n0.3,7\n")
    result = dsim.simulate(scenes["single"], inputs=path, stop=0.5)
    assert result["slave uno.realInEcho"].tolist() == [1.0, 1.0, 1.0, 1.0, 7.0, 7.0]


@pytest.mark.parametrize("scene, column", [
    ("spring_mass_nonlinear", "left.P.f_x"),  # the conventional PORT.f_DOF
    ("frame_split", "rail_left.port1[2].f_x"),  # a member of a node set glued as one port
])
def test_a_column_on_a_glued_ports_force_is_refused_by_the_plan(built, tmp_path, scene,
                                                                column):
    """The joints' own port dofs say which inputs are glued forces: a node set's members
    and a port map's variables as well as PORT.f_DOF (the table's check guessed the last
    only, and let a node set's member through)."""
    from dsim.master.errors import InputError

    table = tmp_path / "load.csv"
    table.write_text(f"time,{column}\n0,0\n1,1\n")
    with pytest.raises(InputError) as error:
        dsim.simulate(built["ssp"] / f"{scene}.ssp", stop=0.01, inputs=table,
                      handle_signals=False)
    [line] = error.value.problems
    assert f"load.csv: column '{column}': '{column}' is a glued port's force: its joint " \
           "sets it every step, no connection or input table may feed it" in line, line
