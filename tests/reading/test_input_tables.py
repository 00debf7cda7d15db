"""Input tables as read (reading/input_tables.py) and as interpolated
(running/tables.py): every form gives the same table; FMPy's rules by hand."""
import numpy as np
import pytest

from dsim.master.errors import InputError
from dsim.master.reading import input_tables
from dsim.master.reading.input_tables import read_table
from dsim.master.running.tables import TableData, left_values, values_at

TIMES = [0.0, 1.0, 1.0, 2.0]
A = [0.0, 2.0, 5.0, 5.0]
B = [1.0, 1.0, 3.0, 0.0]


def _same(table, names=("a.x", "b.y")):
    assert table.names == tuple(names)
    assert table.times.tolist() == TIMES
    assert table.values.tolist() == [A, B]


def test_csv_mat_frame_and_structured_array_give_one_table(tmp_path):
    from scipy.io import savemat

    path = tmp_path / "t.csv"
    path.write_text('"time", a.x ,b.y\n' + "".join(
        f"{t},{a},{b}\n" for t, a, b in zip(TIMES, A, B)) + "\n")
    _same(read_table(path))
    savemat(tmp_path / "dsim.mat", {"time": TIMES, "data": np.column_stack([A, B]),
                                    "names": np.array(["a.x", "b.y"], dtype=object)})
    _same(read_table(tmp_path / "dsim.mat"))
    # MATLAB's a.x = ...; b.y = ...: a struct per component
    savemat(tmp_path / "structs.mat", {"time": TIMES, "a": {"x": A}, "b": {"y": B}})
    _same(read_table(tmp_path / "structs.mat"))
    array = np.array(list(zip(TIMES, A, B)), dtype=[("time", float), ("a.x", float),
                                                     ("b.y", float)])
    _same(read_table(array))
    pandas = pytest.importorskip("pandas")
    _same(read_table(pandas.DataFrame({"time": TIMES, "a.x": A, "b.y": B})))
    _same(read_table(pandas.DataFrame({"a.x": A, "b.y": B}, index=TIMES)))


def test_bad_forms_are_one_line(tmp_path):
    from scipy.io import savemat

    array = np.array([(0.0, 1.0)], dtype=[("t", float), ("a.x", float)])
    with pytest.raises(InputError, match="the first field is 't'"):
        read_table(array)
    with pytest.raises(InputError, match="is not an input table"):
        read_table([1, 2, 3])
    savemat(tmp_path / "short.mat", {"time": [0.0, 1.0], "x": [1.0, 2.0, 3.0]})
    with pytest.raises(InputError, match="'x' has 3 values, 'time' 2"):
        read_table(tmp_path / "short.mat")
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all" * 20)
    with pytest.raises(InputError, match="not a MATLAB .mat file"):
        read_table(tmp_path / "junk.mat")
    pandas = pytest.importorskip("pandas")
    with pytest.raises(InputError, match="row 2, column 'a.x': 'x' is not a number"):
        read_table(pandas.DataFrame({"time": [0.0, 1.0], "a.x": [1.0, "x"]}))


def test_a_file_over_the_limits_is_refused_before_it_is_parsed(tmp_path, monkeypatch):
    path = tmp_path / "big.csv"
    path.write_text("time,a.x\n" + "0,1\n" * 100)
    monkeypatch.setattr(input_tables, "MAX_BYTES", 100)
    with pytest.raises(InputError, match="more than an input table's 100 bytes"):
        read_table(path)
    monkeypatch.setattr(input_tables, "MAX_BYTES", 10 ** 9)
    monkeypatch.setattr(input_tables, "MAX_CELLS", 50)
    path.write_text("time,a.x\n" + "0,2\n" * 100)  # (another content: read again)
    with pytest.raises(InputError, match="more than an input table's 50 cells"):
        read_table(path)


def test_fmpy_rules_by_hand():
    data = TableData(np.array(TIMES), np.array([A, B]), (False, True))
    # before the first row: held; linear in between; a jump at 1.0 (the second row's at
    # and after it); after the last: held; the held column: the last row at or before
    assert values_at(data, -1.0).tolist() == [0.0, 1.0]
    assert values_at(data, 0.25).tolist() == [0.5, 1.0]
    assert values_at(data, 1.0).tolist() == [5.0, 3.0]
    assert values_at(data, 1.0 - 1e-12).tolist() == [5.0, 3.0]  # round-off: at the jump
    assert values_at(data, 1.5).tolist() == [5.0, 3.0]
    assert values_at(data, 9.0).tolist() == [5.0, 0.0]
    # just before a time: the left limit (a step that ends at the jump ramps to 2)
    assert left_values(data, 1.0).tolist() == [2.0, 1.0]
    assert left_values(data, 0.5).tolist() == [1.0, 1.0]
    assert left_values(data, 2.0).tolist() == [5.0, 3.0]
    # a jump at the very first time: the second row's value from it on
    first = TableData(np.array([0.0, 0.0, 1.0]), np.array([[-1.0, 1.0, 1.0]]), (False,))
    assert values_at(first, 0.0).tolist() == [1.0]
    assert values_at(first, -1.0).tolist() == [-1.0]
