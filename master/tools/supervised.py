"""What a supervised ``dsim run`` process says to its supervisor
(:mod:`dsim.master.tools.supervisor`): where its files are."""
from __future__ import annotations

import json
import os

#: set in the child's environment: it runs the command itself
SUPERVISED = "DSIM_SUPERVISED"
#: the child's end of the pipe on which it says where its files are (:func:`report`)
REPORT_FD = "DSIM_SUPERVISOR_FD"


def report(**files) -> None:
    """In a supervised child: tell the supervisor where the run's files are (``csv``,
    ``statistics``, ``checkpoints``, ``scene``, ``restarts``); nothing elsewhere."""
    fd = os.environ.get(REPORT_FD)
    if not fd or not os.environ.get(SUPERVISED):
        return
    line = (json.dumps({k: None if v is None else (v if isinstance(v, (int, float)) else
                                                   str(v)) for k, v in files.items()})
            + "\n").encode()
    try:
        os.write(int(fd), line)
    except (OSError, ValueError):
        pass  # no supervisor listening: the run goes on
