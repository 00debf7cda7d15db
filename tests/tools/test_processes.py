"""The one answer to "does this process still run" (dsim.master.processes), with the
variants its three users need: a zombie, and a pid given again to a later process."""
from __future__ import annotations

import os
import subprocess
import sys
import time

from dsim.master.processes import process_alive, process_start_time


def test_a_running_process_is_alive_and_known_by_its_start_time():
    pid = os.getpid()
    assert process_alive(pid) and process_alive(pid, started=process_start_time(pid))
    assert not process_alive(pid, started=str(int(process_start_time(pid)) + 1))  # pid reused


def test_an_ended_child_is_a_zombie_until_collected_then_gone():
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    deadline = time.monotonic() + 10
    while process_alive(child.pid, zombies=False) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not process_alive(child.pid, zombies=False)  # it has ended
    assert process_alive(child.pid)  # a zombie still holds its pid
    child.wait()
    assert not process_alive(child.pid)
