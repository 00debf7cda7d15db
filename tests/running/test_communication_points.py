"""Communication points are start + n * step, computed, never summed, and no step
ends past the stop time, also in an FMU's own sum t + h (master/running/timeline.py): a C
block that refuses a step ending past its stopTime by any amount (failure 8, as
some tools' FMUs do) runs every step size / stop time pair to the end."""
import itertools
from fractions import Fraction

import numpy as np
import pytest

import dsim
from dsim.master.running.timeline import halves, size_to, step_count
from tests.support.scene_files import component, scene_folder, ssd

STEPS = (0.1, 0.003, 1e-3, 1e-4, 1 / 3)
#: stops that are whole numbers of some of these steps (0.01, 0.3, 1, 2) and not
STOPS = (0.01, 0.02, 0.3, 0.7, 1.0, 2.0, 0.0105, 1.234567)
STARTS = (0.0, 0.1, 1.0 / 7)


def points(start: float, stop: float, step: float):
    """(t, h) handed to the FMUs for every step, as the execution makes them."""
    n = step_count(start, stop, step)
    times = [start + i * step for i in range(n)] + [stop]
    return [(times[i], step if i + 1 < n else size_to(times[i], stop, step))
            for i in range(n)]


@pytest.mark.parametrize("start", STARTS)
def test_no_step_ends_past_the_stop_time_in_the_fmus_own_sum(start):
    for step, stop in itertools.product(STEPS + (0.2, 0.05, 1e-5, 0.7), STOPS):
        if stop <= start or (stop - start) / step > 2e5:
            continue
        steps = points(start, stop, step)
        assert all(t + h <= stop for t, h in steps), (start, stop, step)
        t, h = steps[-1]
        assert t + h == stop, (start, stop, step)  # the last step lands on it exactly
        # whole numbers of steps (decimally) take exactly that many steps, all nominal
        ratio = Fraction(str(stop)) / Fraction(str(step)) if start == 0 else None
        if ratio is not None and ratio.denominator == 1:
            assert len(steps) == ratio.numerator
            assert abs(h - step) <= 1e-9 * step


def test_the_summed_tenth_step_of_a_millisecond_is_the_reported_case():
    # the case of the issue: summed, the tenth step ends at 0.010000000000000002
    t = 9 * 0.001
    assert t + 0.001 > 0.01
    assert t + size_to(t, 0.01, 0.001) == 0.01


@pytest.mark.parametrize("depth", [1, 2, 3])
def test_a_cut_last_step_ends_at_the_stop_time_too(depth):
    for step, stop in itertools.product(STEPS, STOPS):
        if stop / step > 2e5:
            continue
        parts = [points(0.0, stop, step)[-1]]
        for _ in range(depth):
            parts = [half for t, h in parts for half in halves(t, h)]
        assert all(t + h <= stop for t, h in parts), (stop, step)
        assert parts[-1][0] + parts[-1][1] == stop


@pytest.fixture(scope="module")
def strict_block(tmp_path_factory):
    """A scene of one C block that refuses to step past its stopTime (failure 8)."""
    from tests.support.third_party.build import c_fmu

    folder = tmp_path_factory.mktemp("strict")
    fmu = c_fmu(folder / "fmus", "block")
    text = ssd("strict", [component("b1", "resources/block.fmu", {"failure": 8},
                                    outputs=["y"])], stop=0.01)
    return scene_folder(folder / "scene", text, {"block.fmu": fmu})


@pytest.mark.parametrize("step", STEPS)
def test_every_step_and_stop_pair_runs_an_fmu_that_checks_its_stop_time(strict_block, step):
    for stop in (0.01, 0.3, 1.0, 2.0, 0.0105, 1.234567):
        if stop / step > 3e4:
            continue
        result = dsim.simulate(strict_block, step=step, stop=stop, handle_signals=False)
        assert result.status == "completed", (step, stop, result.message)
        n = step_count(0.0, stop, step)
        time = result.signals["time"]
        assert result.steps == n and len(time) == n + 1
        assert time[-1] == stop and np.all(np.diff(time) > 0)
        # computed points, never summed: start + i * step up to the last
        assert np.array_equal(time[:-1], np.arange(n) * step)
