"""What an FMU that embeds Python adds to ``sys.path`` (pythonfmu puts its resources
folder at the front once per instance and never takes it out): held once while its
instances live, gone when the last one is freed (master/running/fmi/python_path.py)."""
import re
import sys

import pytest

import dsim
from dsim.master.recording.observers import Observer
from tests.support.scenes import chain_scene


class PathWatch(Observer):
    """The extracted FMU folders on ``sys.path`` at every row of a run."""

    def __init__(self):
        self.seen = []

    def stepped(self, record):
        self.seen.append([p for p in sys.path if "dsim-fmu" in p])


def test_twelve_instances_hold_their_folder_once_and_a_run_leaves_sys_path_as_it_was(
        built, tmp_path):
    """Before: 12 copies during the run, 12 left after it, 12 more per run."""
    folder = chain_scene(tmp_path / "chain", built, 12)
    before = list(sys.path)
    for run in range(2):
        watch = PathWatch()
        result = dsim.simulate(folder, stop=0.005, out=tmp_path / f"run{run}.csv",
                               observers=[watch], handle_signals=False)
        assert result.status == "completed" and len(watch.seen) == 6
        for entries in watch.seen:
            assert len(entries) == 1 and entries[0].endswith("resources"), entries
        assert sys.path == before


def test_an_instance_the_fmu_refuses_gives_its_entry_back(built, tmp_path):
    """The third mass asks for 99 masses: the FMU refuses it in initialization (bad
    input, exit 2 on the command line), every instance is freed, ``sys.path`` is as it
    was."""
    folder = chain_scene(tmp_path / "chain", built, 4)
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    third = text.index('name="m3"')
    n = re.compile(r'(<ssv:Parameter name="n">\s*<ssv:Integer value=")1(")')
    ssd.write_text(text[:third] + n.sub(r"\g<1>99\g<2>", text[third:], count=1))
    before = list(sys.path)
    with pytest.raises(dsim.InputError, match="m3"):
        dsim.simulate(folder, stop=0.005, out=tmp_path / "run.csv", handle_signals=False)
    assert sys.path == before
