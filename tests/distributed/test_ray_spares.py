"""Spare workers (master/running/backends/ray/spares.py) on the session's local Ray
instance: a run of a driver that joined Ray leaves as many fresh workers as it used,
the next run takes them with its numbers unchanged to the last bit, a spare that died
while it waited is replaced, and the isolated backend leaves none."""
import os
import signal
import time

import dsim
from dsim.master.running.backends.ray import spares as ray_spares
from tests.support.runs import same_run, workers


def stop_after(scene, steps: int) -> float:
    found = dsim.prepare(scene).scene
    return found.start_time + steps * found.master.step


def gone(pid: int, within: float = 30.0) -> bool:
    """Whether process ``pid`` has ended (waiting ``within`` s at most)."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False


def test_a_run_leaves_fresh_spares_and_the_next_run_takes_them(built, ray_local):
    scene = built["ssp"] / "frame_split.ssp"  # five elastic bodies on two workers
    stop = stop_after(scene, 5)
    here = dsim.simulate(scene, stop=stop)
    ray_spares.drop(ray_local)
    first = dsim.simulate(scene, stop=stop, backend="ray")
    used = workers(first)
    assert len(used) == 2 and ray_spares.count() == 2
    assert ray_spares.settle(ray_local) == 2
    spares = ray_spares.pids(ray_local)
    assert len(spares) == 2 and not spares & used  # new processes, not the run's own
    second = dsim.simulate(scene, stop=stop, backend="ray")
    assert workers(second) == spares  # taken, not started anew
    assert {c["worker"]["started"] for c in second.statistics["components"].values()} \
        == {"ahead"}
    same_run(here, first)
    same_run(here, second)
    ray_spares.settle(ray_local)
    assert not ray_spares.pids(ray_local) & (used | spares)  # never a process twice
    ray_spares.drop(ray_local)
    assert ray_spares.count() == 0


def test_a_spare_that_died_while_it_waited_is_replaced(built, ray_local):
    scene = built["ssp"] / "frame_split.ssp"
    stop = stop_after(scene, 5)
    ray_spares.drop(ray_local)
    here = dsim.simulate(scene, stop=stop, backend="ray")
    ray_spares.settle(ray_local)
    victim = min(ray_spares.pids(ray_local))
    os.kill(victim, signal.SIGKILL)
    assert gone(victim)
    there = dsim.simulate(scene, stop=stop, backend="ray")
    assert there.ok and victim not in workers(there) and len(workers(there)) == 2
    same_run(here, there)
    ray_spares.drop(ray_local)


def test_the_isolated_backend_leaves_no_spare(built, ray_local):
    scene = built["ssp"] / "spring_mass_linear.ssp"
    ray_spares.drop(ray_local)
    result = dsim.simulate(scene, stop=stop_after(scene, 5), backend="isolated")
    assert result.ok and ray_spares.count() == 0


def test_spares_turned_off_are_neither_left_nor_taken(built, ray_local):
    scene = built["ssp"] / "spring_mass_linear.ssp"
    stop = stop_after(scene, 5)
    ray_spares.drop(ray_local)
    dsim.simulate(scene, stop=stop, backend="ray")
    assert ray_spares.count() == 2
    try:
        ray_spares.keep(False)  # also what DSIM_RAY_SPARES=0 does
        assert ray_spares.count() == 0 and not ray_spares.keeping()
        result = dsim.simulate(scene, stop=stop, backend="ray")
        assert result.ok and ray_spares.count() == 0
    finally:
        ray_spares.keep(True)


def test_the_environment_turns_spares_off_for_a_process():
    import subprocess
    import sys

    code = "from dsim.master.running.backends.ray import spares as ray_spares; print(ray_spares.keeping())"
    said = {value: subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                  env={**os.environ, "DSIM_RAY_SPARES": value},
                                  check=True).stdout.strip()
            for value in ("0", "1", "")}
    assert said == {"0": "False", "1": "True", "": "True"}


def test_workers_started_ahead_of_a_first_run_are_the_ones_it_takes(built, ray_local):
    """dsim.simulate(..., backend="ray") on a Ray instance the script joined starts the
    workers (ray_spares.ahead) before it reads and plans the scene."""
    scene = built["ssp"] / "frame_split.ssp"
    stop = stop_after(scene, 5)
    ray_spares.drop(ray_local)
    assert ray_spares.ahead(ray_local) == 2 and ray_spares.ahead(ray_local) == 0  # topped up
    ray_spares.settle(ray_local)
    started = ray_spares.pids(ray_local)
    result = dsim.simulate(scene, stop=stop, backend="ray")
    assert result.ok and workers(result) == started
    ray_spares.drop(ray_local)


def test_workers_started_ahead_of_a_refused_scene_stay_as_spares(ray_local, tmp_path):
    import pytest

    from dsim.master.errors import InputError

    missing = tmp_path / "nothing_here.ssp"
    ray_spares.drop(ray_local)
    with pytest.raises(InputError):
        dsim.simulate(missing, stop=0.1, backend="ray")
    assert ray_spares.count() == 2  # one per CPU of the session's instance, for the next run
    ray_spares.drop(ray_local)
