"""A set-up of thousands of FMUs takes seconds: the observers are told how far it is
(`Observer.preparing`), and the progress line on a terminal says it."""
import io

import dsim
from dsim.master.recording.observers import Observer, ProgressBar
from dsim.master.running.execution import Execution
from tests.test_python_path import chain_scene


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
