"""The result of a run in Python (master/recording/results.py): a missing column names
the closest, and to_pandas is the signals indexed by time."""
import sys

import numpy as np
import pytest

import dsim


def test_a_missing_column_names_the_closest(built):
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.05,
                           handle_signals=False)
    with pytest.raises(KeyError) as missing:
        result["right.y[2]"]
    assert "no column 'right.y[2]' in the results (closest: right.x[2]" in str(missing.value)
    assert missing.value.closest[0] == "right.x[2]"
    assert np.array_equal(result["right.x[2]"], result.signals["right.x[2]"])


def test_to_pandas_is_the_signals_indexed_by_time(built, tmp_path, monkeypatch):
    pandas = pytest.importorskip("pandas")
    result = dsim.simulate(built["ssp"] / "spring_mass_linear.ssp", stop=0.05,
                           out=tmp_path / "r.csv", handle_signals=False)
    frame = result.to_pandas()
    assert frame.index.name == "time" and list(frame.columns) == [
        n for n in result.signals if n != "time"]
    assert np.array_equal(frame["right.x[2]"].to_numpy(), result["right.x[2]"])
    assert np.array_equal(frame.index.to_numpy(), result["time"])
    read = pandas.read_csv(tmp_path / "r.csv", index_col="time")
    assert np.allclose(read.to_numpy(), frame.to_numpy(), rtol=1e-15, atol=0)
    monkeypatch.setitem(sys.modules, "pandas", None)  # as if it were not installed
    with pytest.raises(ImportError, match="pip install pandas"):
        result.to_pandas()
