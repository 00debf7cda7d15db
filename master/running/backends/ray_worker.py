"""The worker side of the Ray backends: the actor that holds some FMU instances in its
process, and how the subsystems are dealt onto workers."""
from __future__ import annotations

import os
from dataclasses import replace

from dsim.master.running.backends.base import terminate_all
from dsim.master.running.fmi import open_subsystem
from dsim.master.running.ray_cluster import landed


class Host:
    """A worker process (the Ray actor): some subsystems, called in order."""

    def __init__(self):
        self.subsystems = []

    def open(self, specs, files) -> dict:
        """Instantiate the FMUs of ``specs`` from the shipped ``files`` (for each, its
        FMU and its scene files by parameter, :class:`~dsim.master.running.ray_cluster.Shipment`);
        where this worker runs."""
        import ray

        for spec, (fmu, scene_files) in zip(specs, files):
            parameters = {**spec.parameters, **{name: ("String", str(landed(shipped)))
                                                for name, shipped in scene_files.items()}}
            self.subsystems.append(open_subsystem(replace(spec, path=landed(fmu),
                                                          parameters=parameters)))
        return {"node": ray.get_runtime_context().get_node_id(), "pid": os.getpid()}

    def run(self, calls) -> list:
        """Each (slot, [(method, arguments), ...]) in order; the results of each
        subsystem's calls (a list per subsystem)."""
        return [[getattr(self.subsystems[slot], method)(*arguments)
                 for method, arguments in steps] for slot, steps in calls]

    def close(self) -> list[Exception]:
        """Terminate every subsystem, even if some fail; the errors they raised."""
        errors, self.subsystems = terminate_all(self.subsystems), []
        return errors


def deal(count: int, workers: int) -> list[list[int]]:
    """Subsystem indices 0..count-1 dealt round-robin onto ``workers`` workers (two
    heavy subsystems declared one after the other land on different workers)."""
    return [list(range(w, count, workers)) for w in range(min(workers, count))]
