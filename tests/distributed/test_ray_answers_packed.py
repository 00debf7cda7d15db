"""What travels between the Ray driver and a worker with thousands of subsystems: the
answers as two arrays (master/running/backends/ray/worker.py, pack_answers: every vector
back to the bit, None where an FMU lacks a kind, answers of another kind sent as they
were), a batch of calls as one pickle whose loaded copy the driver keeps, and each
checkpoint as the worker pickled it."""
import pickle

import numpy as np

from dsim.master.running.backends.ray.worker import pack_answers, unpack_answers


def round_trip(answers):
    packed = pack_answers(answers)
    return None if packed is None else unpack_answers(*pickle.loads(pickle.dumps(packed)))


def same(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    if isinstance(a, tuple):
        return isinstance(b, tuple) and len(a) == len(b) and all(map(same, a, b))
    return b.dtype == np.float64 and a.tobytes() == b.tobytes()


def test_steps_and_reads_come_back_to_the_bit_with_their_gaps():
    rng = np.random.default_rng(3)
    odd = np.array([np.nan, -0.0, 5e-324, np.inf])
    steps = [[(rng.standard_normal(2), None, rng.standard_normal(2)), rng.random(3)],
             [(odd, odd[:2].copy(), None), np.zeros(0)],
             [(None, None, None), rng.random(1)]]
    back = round_trip(steps)
    assert len(back) == 3 and all(same(x, y) for s, b in zip(steps, back)
                                  for x, y in zip(s, b))
    back[0][1][0] = 7.0  # writable, and no other vector moves
    assert back[1][0][0].tobytes() == odd.tobytes()
    reads = [[rng.random(2)], [None], [odd]]  # read_outputs, set_forces (None) and the like
    assert all(same(s[0], b[0]) for s, b in zip(reads, round_trip(reads)))
    kinematics = [[(rng.random(1), rng.random(1), None)] for _ in range(4)]
    assert all(same(s[0], b[0]) for s, b in zip(kinematics, round_trip(kinematics)))


def test_answers_of_other_kinds_or_forms_are_not_packed():
    kinematics = (np.zeros(2), None, None)
    assert pack_answers([]) is None
    assert pack_answers([[kinematics, np.zeros(1)], [kinematics]]) is None  # two forms
    assert pack_answers([[kinematics], [np.zeros(2)]]) is None
    assert pack_answers([[np.arange(2)]]) is None  # not float64
    assert pack_answers([[np.zeros((2, 2))]]) is None
    assert pack_answers([[{"fmi2DoStep": [3, 0.1]}]]) is None  # statistics
    assert pack_answers([[["text"]]]) is None and pack_answers([[(1, 2)]]) is None


def test_a_batch_travels_as_one_pickle_and_the_driver_keeps_the_values_sent():
    from dsim.master.running.backends.ray.backend import _pickled, _unpacked

    forces = np.array([1.5, -0.0, np.nan])
    batch = [(0, [("trial_step", (forces, 0.25, 1e-3))]), (1, [("@checkpoint", ())])]
    sent = _pickled(batch)
    kept = pickle.loads(sent)
    forces[0] = 99.0  # the coupling reuses its vectors: what was sent must not move
    assert kept[0][1][0][1][0].tobytes() == np.array([1.5, -0.0, np.nan]).tobytes()
    assert kept[1] == (1, [("@checkpoint", ())])
    assert _pickled([(0, [("call", (lambda: 1,))])]) is None  # sent as it is, by Ray
    # a worker's answer, as bytes (run_pickled) or as it is, reads the same
    answer = ([["ahead"]], pack_answers([[np.arange(3.0)]]), None)
    assert str(_unpacked(pickle.dumps(answer))) == str(_unpacked(answer)) == \
        "[['ahead'], [array([0., 1., 2.])]]"


def test_the_driver_keeps_a_checkpoint_as_the_worker_pickled_it_and_marks_a_failed_one():
    from dsim.master.running.backends.ray.backend import RayBackend, _Cluster

    cluster = _Cluster(None, [None], [["a", "b"]])
    cluster.unrestartable, cluster.restarts_left = [None], 1
    cluster.checkpoints = {(0, 0): None, (0, 1): None}
    before = [(0, [("set_forces", (np.zeros(1),))])]
    cluster.log = {0: [(pickle.dumps(before), None)]}
    backend = RayBackend(cluster, [(0, 0), (0, 1)], ["a", "b"])
    saved = pickle.dumps({"state": {"fmu": b"\x00"}, "start": [], "inputs": []})
    forces = np.ones(1)
    batch = [(0, [("@checkpoint", ()), ("trial_step", (forces, 0.0, 1e-3))])]
    backend._journal(0, batch, [[saved, None]], pickle.dumps(batch))
    forces[0] = 7.0  # the coupling reuses its vectors: the journal keeps what was sent
    assert cluster.checkpoints[(0, 0)] is saved  # bytes, not loaded in the driver
    assert len(cluster.log[0]) == 2  # 'b' has saved no state yet: the first batch stays
    journaled = backend._journaled(0)
    assert [call[0] for call in journaled[0]] == ["trial_step"]
    assert journaled[0][0][1][0].tolist() == [1.0]
    assert cluster.unrestartable == [None]
    both = [(0, [("@checkpoint", ())]), (1, [("@checkpoint", ()), ("advance", (forces,))])]
    backend._journal(0, both, [[saved], [saved, None]], pickle.dumps(both))
    assert len(cluster.log[0]) == 1  # both saved: the batches before are needed no more
    assert {slot: [c[0] for c in calls] for slot, calls in backend._journaled(0).items()} \
        == {0: [], 1: ["advance"]}
    backend._journal(0, [(1, [("@checkpoint", ())])], [[{"error": "OSError: no room"}]],
                     None)
    assert cluster.unrestartable[0] == ("component 'b' could not serialize its state "
                                        "(OSError: no room)")


def test_a_journal_of_a_subsystem_never_saved_is_boiled_down_not_kept_whole():
    """A worker with a subsystem in no joint (never saved): its journal is boiled down
    to each subsystem's calls since its checkpoint every few batches, as they were
    sent, a failed call marked."""
    from dsim.master.running.backends.ray.backend import RayBackend, _Cluster
    from dsim.master.running.backends.ray.recovery import LOG_BATCHES

    cluster = _Cluster(None, [None], [["glued", "free"]])
    cluster.unrestartable, cluster.restarts_left = [None], 1
    cluster.checkpoints = {(0, 0): None, (0, 1): None}
    cluster.log = {0: []}
    backend = RayBackend(cluster, [(0, 0), (0, 1)], ["glued", "free"])
    for step in range(3 * LOG_BATCHES):
        batch = [(0, [("@checkpoint", ()), ("trial_step", (np.full(1, step),))]),
                 (1, [("exchange", (float(step), 1e-3))])]
        backend._journal(0, batch, [[b"state", None], [None]], pickle.dumps(batch))
        assert len(cluster.log[0]) <= LOG_BATCHES
    failed = [(1, [("exchange", (99.0, 1e-3)), ("read_outputs", ())])]
    backend._journal_failed(0, (0, 1), pickle.dumps(failed))
    journaled = backend._journaled(0)
    assert [c[1][0].tolist() for c in journaled[0]] == [[3 * LOG_BATCHES - 1]]
    assert [c[1][0] for c in journaled[1][:-2]] == [float(s) for s in range(3 * LOG_BATCHES)]
    assert journaled[1][-2:] == [("exchange", (99.0, 1e-3)), ("@failed", ("read_outputs", ()))]
