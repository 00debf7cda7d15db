"""Comparing runs and reading what a command said: two results equal to the bit, the
processes that ran a result's components, a ``dsim run`` and its error lines."""
from __future__ import annotations

import numpy as np

from dsim.master.tools.cli import main


def same_run(here, there) -> None:
    """Two results of one scene hold the same numbers, bit for bit."""
    assert (there.status, there.message, there.steps) == (here.status, here.message,
                                                         here.steps)
    assert list(there.signals) == list(here.signals)
    for column, values in here.signals.items():
        assert np.array_equal(there[column], values), column
    for name, counts in here.statistics["components"].items():
        other = there.statistics["components"][name]
        assert (other["do_steps"], other["state_saves"], other["state_restores"]) == (
            counts["do_steps"], counts["state_saves"], counts["state_restores"]), name


def workers(result) -> set[int]:
    """The process ids that ran the result's components."""
    return {c["worker"]["pid"] for c in result.statistics["components"].values()}


def run_cli(capsys, *args) -> tuple[int, list[str]]:
    """``dsim run ARGS --quiet`` in this process: its exit code and its error lines."""
    code = main(["run", *map(str, args), "--quiet"])
    return code, capsys.readouterr().err.strip().splitlines()


def one_error(capsys) -> str:
    """The one line a command wrote to stderr (no traceback)."""
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in lines[0], lines
    return lines[0]
