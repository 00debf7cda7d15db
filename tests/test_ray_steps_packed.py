"""A Ray worker's answers to a batch of steps travel as two arrays
(master/running/backends/ray_worker.py, pack_steps): every vector back to the bit,
None where an FMU lacks a kind, anything else sent as it was."""
import pickle

import numpy as np

from dsim.master.running.backends.ray_worker import pack_steps, unpack_steps


def test_steps_come_back_to_the_bit_with_their_gaps():
    rng = np.random.default_rng(3)
    odd = np.array([np.nan, -0.0, 5e-324, np.inf])
    answers = [[(rng.standard_normal(2), None, rng.standard_normal(2)), rng.random(3)],
               [(odd, odd[:2].copy(), None), np.zeros(0)],
               [(None, None, None), rng.random(1)]]
    values, sizes = pickle.loads(pickle.dumps(pack_steps(answers)))  # as Ray carries it
    back = unpack_steps(values, sizes)
    assert len(back) == 3 and sizes.tolist() == [2, -1, 2, 3, 4, 2, -1, 0, -1, -1, -1, 1]
    for sent, got in zip(answers, back):
        for a, b in zip((*sent[0], sent[1]), (*got[0], got[1])):
            assert (a is None and b is None) or (b.dtype == np.float64
                                                 and a.tobytes() == b.tobytes())
    back[0][1][0] = 7.0  # writable, and no other vector moves
    assert back[1][0][0].tobytes() == odd.tobytes()


def test_an_answer_of_another_shape_is_not_packed():
    kinematics = (np.zeros(2), None, None)
    assert pack_steps([[kinematics, np.zeros(1)], [kinematics]]) is None
    assert pack_steps([[kinematics, np.arange(2)]]) is None  # not float64
    assert pack_steps([[(np.zeros((2, 2)), None, None), np.zeros(1)]]) is None
    values, sizes = pack_steps([])
    assert unpack_steps(values, sizes) == []
