"""Everything of dsim that knows Ray, in one folder.

The rest of dsim reaches it through the backend protocol (``RayBackend`` and
``IsolatedBackend``, registered in ``BACKENDS``: ``Backend.ahead``, ``release_ahead``,
``log_line``) and through one entry for sweeps (:func:`run_points`, and
:class:`HeadLost` when the cluster's head is lost under a sweep).  Inside:

- ``backend.py``: the two backends (one worker per FMU, or per group of FMUs);
- ``worker.py``: the worker actor that hosts a run's subsystems;
- ``recovery.py``: a lost worker started again from its last checkpoint;
- ``placement.py``: which node each worker goes to;
- ``spares.py``, ``pool.py``, ``lease.py``: workers started ahead, for a script's
  next run and, in a cluster, for the next command;
- ``cluster.py``: joining or starting Ray, shipping files, watching the head, Ray's log;
- ``points.py``: the points of a sweep as Ray tasks.

Ray itself is imported only when a run or a sweep uses it (it is an optional extra).
"""
from dsim.master.running.backends.ray.backend import IsolatedBackend, RayBackend
from dsim.master.running.backends.ray.points import HeadLost, run_points

__all__ = ["HeadLost", "IsolatedBackend", "RayBackend", "run_points"]
