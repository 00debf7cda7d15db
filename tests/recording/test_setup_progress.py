"""A set-up of thousands of FMUs takes seconds: the observers are told how far it is
(`Observer.preparing`), and the progress line on a terminal says it."""
import io

import dsim
from dsim.master.recording.observers import Observer, ProgressBar
from dsim.master.running.execution import Execution
from tests.support.scenes import chain_scene


class Told(Observer):
    def __init__(self):
        self.events = []

    def preparing(self, what, done, total):
        self.events.append((what, done, total))

    def stepped(self, record):
        self.events.append(("stepped", record.index))


def test_every_instance_is_told_then_the_initialisation_then_the_start(built, tmp_path,
                                                                       monkeypatch):
    monkeypatch.setattr(Execution, "PREPARING_EVERY", 0.0)  # every instance, not 5 a second
    told = Told()
    result = dsim.simulate(chain_scene(tmp_path / "chain", built, 30), stop=0.002,
                           out=tmp_path / "run.csv", observers=[told], handle_signals=False)
    assert result.status == "completed"
    instantiated = [e for e in told.events if e[0] == "FMUs instantiated"]
    assert instantiated == [("FMUs instantiated", k, 30) for k in range(1, 31)]
    after = told.events[len(instantiated):]
    assert after[:2] == [("initialising", 0, 0), ("stepped", 0)]


def test_a_notice_a_fifth_of_a_second_at_most_and_always_the_last(built, tmp_path):
    told = Told()
    dsim.simulate(chain_scene(tmp_path / "chain", built, 30), stop=0.002,
                  out=tmp_path / "run.csv", observers=[told], handle_signals=False)
    instantiated = [e for e in told.events if e[0] == "FMUs instantiated"]
    # 30 instances take well under a second: the first and the last (or a few between)
    assert instantiated[0] == ("FMUs instantiated", 1, 30) and len(instantiated) < 10
    assert instantiated[-1] == ("FMUs instantiated", 30, 30)


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_the_progress_line_says_how_far_the_set_up_is(built, tmp_path):
    screen = Terminal()
    bar = ProgressBar(label="chain", stream=screen)
    result = dsim.simulate(chain_scene(tmp_path / "chain", built, 12), stop=0.002,
                           out=tmp_path / "run.csv", observers=[bar], handle_signals=False)
    assert result.status == "completed"
    shown = screen.getvalue()
    assert "chain · FMUs instantiated 12/12" in shown and "chain · initialising" in shown


#: a run on a local Ray instance it starts itself: what its observer is told first
STARTS_RAY = """
import json, sys
import dsim
from dsim.master.recording.observers import Observer

class Told(Observer):
    events = []
    def preparing(self, what, done, total):
        self.events.append([what, done, total])

result = dsim.simulate(sys.argv[1], stop=0.002, observers=[Told()], backend="ray",
                       handle_signals=False)
print(json.dumps([result.status, Told.events]))
"""


def test_starting_ray_is_said_before_the_instances_and_only_when_it_starts(built,
                                                                          ray_local):
    """Starting a local Ray instance takes seconds with nothing else to show: the line
    says it; a run on a Ray instance already there says nothing of it."""
    import json
    import subprocess
    import sys

    scene = str(built["ssp"] / "chain_10.ssp")
    said = subprocess.run([sys.executable, "-c", STARTS_RAY, scene], capture_output=True,
                          text=True, check=True).stdout
    status, events = json.loads(said.splitlines()[-1])
    assert status == "completed"
    assert events[:2] == [["starting a local Ray instance", 0, 0],
                          ["FMUs instantiated", 10, 10]], events
    told = Told()
    assert dsim.simulate(scene, stop=0.002, observers=[told], backend="ray",
                         handle_signals=False).ok
    assert [e for e in told.events if e[0] != "stepped"][:1] == [("FMUs instantiated", 10, 10)]
