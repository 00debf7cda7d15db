"""Backends: where the subsystems run (a registry; ``backend=`` names one).

A backend owns the subsystems of a run and answers the couplings' batched calls
for all of them (or for a subset: :meth:`Backend.subset`), so that a parallel
backend can run them side by side without the algorithm knowing.
"""
from dsim.master.running.backends.base import Backend
from dsim.master.running.backends.inprocess import InProcessBackend
from dsim.master.running.backends.ray import IsolatedBackend, RayBackend

# the Ray backends import Ray only when a run uses them (it is an optional extra)
BACKENDS = {backend.name: backend for backend in (InProcessBackend, RayBackend,
                                                   IsolatedBackend)}


def log_lines() -> list[str]:
    """After a failure: where each backend's own processes wrote what they said
    meanwhile (Ray's log), one line each; none for a run in this process only."""
    lines = (backend.log_line() for backend in BACKENDS.values())
    return list(dict.fromkeys(line for line in lines if line))  # Ray and isolated: one log


__all__ = ["BACKENDS", "Backend", "InProcessBackend", "IsolatedBackend", "RayBackend",
           "log_lines"]
