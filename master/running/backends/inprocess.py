"""Every subsystem in this process, called one after the other; a system without
joints steps through a :class:`~dsim.master.running.fmi.causal_kernel.CausalKernel`."""
from __future__ import annotations

from dsim.master.running.backends.base import Backend, terminate_all
from dsim.master.running.collector import collector_paused, freeze, thaw
from dsim.master.running.fmi import open_subsystem
from dsim.master.running.fmi.causal_kernel import CausalKernel


class InProcessBackend(Backend):
    """The subsystems live in this process and are called in order."""

    name = "in-process"

    def __init__(self, subsystems):
        self.subsystems = list(subsystems)
        self._frozen = False

    @classmethod
    def from_specs(cls, specs, progress=None, **options) -> "InProcessBackend":
        subsystems, specs = [], list(specs)
        try:
            with collector_paused():  # thousands of instances: see collector.py
                for spec in specs:
                    subsystems.append(open_subsystem(spec))
                    if progress is not None:
                        progress(len(subsystems), len(specs))
        except BaseException:
            cls(subsystems).close()
            raise
        backend = cls(subsystems)
        # the scene, its plan and the instances live as long as the run: out of the
        # collector's passes until it is closed (collector.py)
        freeze()
        backend._frozen = True
        return backend

    def subset(self, indices) -> "InProcessBackend":
        return InProcessBackend([self.subsystems[i] for i in indices])

    def __len__(self) -> int:
        return len(self.subsystems)

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.subsystems]

    def begin_step(self) -> None:
        for subsystem in self.subsystems:
            subsystem.begin_step()

    def trial_step(self, forces, time, step_size):
        return [s.trial_step(f, time, step_size) for s, f in zip(self.subsystems, forces)]

    def advance(self, forces, time, step_size):
        return [s.advance(f, time, step_size) for s, f in zip(self.subsystems, forces)]

    def step(self, time, step_size, inputs=()):
        subsystems = self.subsystems
        if not inputs:
            return [s.exchange(time, step_size) for s in subsystems]
        given = [None] * len(subsystems)
        for index, values in inputs:
            given[index] = values
        # each subsystem's inputs, step and outputs in one call (the inputs were all
        # computed from the step start's outputs: the order of the FMUs changes nothing)
        return [s.exchange_with(v, time, step_size) for s, v in zip(subsystems, given)]

    def causal_kernel(self, transfer, outputs) -> "CausalKernel":
        return CausalKernel(self.subsystems, transfer, outputs)

    def hold_inputs(self, ramps) -> None:
        for subsystem, (start, end, step_size) in zip(self.subsystems, ramps):
            subsystem.hold_inputs(start, end, step_size)

    def trial_exchange(self, time, step_size, ramps):
        return [s.trial_exchange(start, end, time, step_size)
                for s, (start, end) in zip(self.subsystems, ramps)]

    def flexibility(self, forces, time, step_size, deltas, bases):
        return [s.flexibility(f, time, step_size, d, b)
                for s, f, d, b in zip(self.subsystems, forces, deltas, bases)]

    snapshots = True

    def snapshot(self) -> list:
        return [s.snapshot() for s in self.subsystems]

    def rollback(self, snapshot) -> None:
        for subsystem, state in zip(self.subsystems, snapshot):
            subsystem.rollback(state)

    def discard(self, snapshot) -> None:
        for subsystem, state in zip(self.subsystems, snapshot):
            subsystem.discard(state)

    def set_forces(self, forces) -> None:
        for subsystem, f in zip(self.subsystems, forces):
            subsystem.set_forces(f)

    def start_flexibility(self, forces, deltas):
        return [s.start_flexibility(f, d) for s, f, d in zip(self.subsystems, forces, deltas)]

    def kinematics(self):
        return [s.kinematics() for s in self.subsystems]

    def read_outputs(self):
        return [s.read_outputs() for s in self.subsystems]

    def write_inputs(self, inputs, start: bool = False) -> None:
        for index, values in inputs:
            if start:
                self.subsystems[index].write_start_inputs(values)
            else:
                self.subsystems[index].write_inputs(values)

    def set_values(self, entries) -> None:
        for index, names, values in entries:
            self.subsystems[index].set_values(names, values)

    def read_texts(self):
        return [s.read_texts() for s in self.subsystems]

    def write_texts(self, inputs) -> None:
        for index, values in inputs:
            self.subsystems[index].write_texts(values)

    def finish_initialization(self) -> None:
        for subsystem in self.subsystems:
            subsystem.finish_initialization()

    def counters(self):
        return [s.statistics() for s in self.subsystems]

    def save_states(self) -> list[dict]:
        return [s.current_checkpoint() for s in self.subsystems]

    def load_states(self, states, counters) -> None:
        for subsystem, state, counted in zip(self.subsystems, states, counters):
            subsystem.resume(state)
            subsystem.restore_counters(counted)

    def close(self) -> list[Exception]:
        try:
            return terminate_all(self.subsystems)
        finally:
            if self._frozen:
                self._frozen = False
                thaw()
