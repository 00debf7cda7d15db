"""An FMU state serialized by dsim's FMUs (fmus/fmi_binding.py, state_to_bytes): pickled
once for pythonfmu's pair of calls (fmi2SerializedFMUstateSize, then
fmi2SerializeFMUstate, with the same state), and never given stale bytes after."""
import pickle

import numpy as np

from dsim.fmus import fmi_binding
from dsim.fmus.fmi_binding import state_from_bytes, state_to_bytes


def test_the_pair_of_calls_pickles_a_state_once_and_a_third_call_pickles_again(monkeypatch):
    made = []
    real = pickle.dumps
    monkeypatch.setattr(fmi_binding.pickle, "dumps",
                        lambda *a, **k: made.append(1) or real(*a, **k))
    state = {"core": {"q": np.arange(3.0)}, "forces": np.zeros(2), "caches": None}
    size = state_to_bytes(state)  # fmi2SerializedFMUstateSize
    data = state_to_bytes(state)  # fmi2SerializeFMUstate
    assert data is size and len(made) == 1
    assert pickle.loads(data)["core"]["q"].tolist() == [0.0, 1.0, 2.0]
    state["forces"][0] = 5.0  # a state changed after the pair (one moved in is, when set)
    again = state_to_bytes(state)
    assert len(made) == 2 and pickle.loads(again)["forces"].tolist() == [5.0, 0.0]


def test_a_moved_state_is_serialized_as_it_is_now():
    moved = state_from_bytes(state_to_bytes({"core": None, "forces": np.ones(1)}))
    state_to_bytes(moved)
    state_to_bytes(moved)  # the pair: "moved" still in it
    moved.pop("moved")  # what set_state does to a state from another instance
    assert "moved" not in pickle.loads(state_to_bytes(moved))
    other = {"core": None, "forces": np.ones(1)}
    first = state_to_bytes(other)
    assert state_to_bytes({"core": None, "forces": np.ones(1)}) is not first  # another object
