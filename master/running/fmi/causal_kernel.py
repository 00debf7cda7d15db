"""The macro step of FMUs in no joint, called from one loop (the in-process backend's
causal kernel): beside
:meth:`~dsim.master.running.fmi.cs2.CoSimulation2Subsystem.fused_step`, which gives it
each FMU's calls, and checked as every FMI call is (``status > WARNING``:
fmi2Discard or worse fails, through the call's own check)."""
from __future__ import annotations

import ctypes
import time as clock

import numpy as np

from dsim.master.running.fmi.messages import WARNING


class CausalKernel:
    """The macro step of subsystems that are in no joint, specialised once: the inputs
    of every connection gathered from the outputs at the step start into one buffer
    (one numpy call), then for each FMU its ``fmi2SetReal`` from that buffer,
    ``fmi2DoStep`` and ``fmi2GetReal`` into one output buffer, called with argument
    objects made at set-up (:meth:`CoSimulation2Subsystem.fused_step`), and one copy of the
    outputs.  A subsystem whose step cannot be fused (another FMI version, inputs of
    another type than Real) takes its :meth:`~Subsystem.exchange_with` in its place.

    Every FMI call is still timed (a clock reading between two calls: each function's
    seconds stay its own) and its status checked before the next call; the calls are
    counted per step and handed to the FMUs' counters when their statistics are asked
    (:meth:`sync`), exactly: a step that fails counts the calls it made."""

    def __init__(self, subsystems, transfer, outputs):
        sizes = [len(part) for part in outputs]
        self.outputs = np.zeros(sum(sizes))
        self.inputs = np.zeros(transfer.size)
        self._gather = transfer.gather
        #: None: every connection copies its value (one np.take), else the transfer
        self._transfer = None if transfer.identity and not transfer.tables else transfer
        self._time = ctypes.c_double(0.0)
        self._size = ctypes.c_double(0.0)
        inputs = {index: (start, stop) for index, start, stop in transfer.targets}
        #: per subsystem (put, its arguments, step, its, get, its, generic): the calls
        #: and arguments of a fused step, or (None, ..., None, (subsystem, inputs,
        #: outputs)) for one called through exchange_with
        self.entries = []
        self.subsystems = list(subsystems)
        self._fused = []  # (subsystem, its calls) of the fused ones
        start = 0
        for index, (subsystem, size) in enumerate(zip(self.subsystems, sizes)):
            span = inputs.get(index)
            given = None if span is None else self.inputs[span[0]:span[1]]
            taken = self.outputs[start:start + size]
            start += size
            fuse = getattr(subsystem, "fused_step", None)
            pieces = fuse(given, taken, self._time, self._size, self) if fuse else None
            if pieces is None:
                self.entries.append((None, None, None, None, None, None,
                                     (subsystem, given, taken)))
                continue
            put, step, get = pieces
            put, put_args = put or (None, None)
            get, get_args = get or (None, None)
            self.entries.append((put, put_args, step[0], step[1], get, get_args, None))
            self._fused.append((subsystem, [c for c in (put, step[0], get) if c is not None]))
        #: macro steps taken whole, and how many of them the FMUs' counters hold
        self.steps = self._counted = 0
        self._at = 0.0  # the last step's start (s)
        #: the subsystem that ended the simulation in the last step (its next raises)
        self._ended = next((s for s in self.subsystems
                            if getattr(s, "ended_at", None) is not None), None)

    def __call__(self, outputs: np.ndarray, time: float, step_size: float) -> np.ndarray:
        """One macro step from ``time`` (s) by ``step_size`` (s) with the inputs computed
        from ``outputs`` (every subsystem's at the step start, flat); the outputs after
        it (a new array)."""
        if self._ended is not None:
            self._ended._raise_ended()
        if self._transfer is None:
            outputs.take(self._gather, out=self.inputs)
        else:
            self.inputs[:] = self._transfer.values(outputs)
        self._time.value = self._at = time
        if step_size != self._size.value:
            self._size.value = step_size
        now = clock.perf_counter
        for put, put_args, step, step_args, get, get_args, generic in self.entries:
            if generic is not None:
                subsystem, given, taken = generic
                taken[:] = subsystem.exchange_with(given, time, step_size)
                continue
            start = now()
            if put is not None:
                status = put.function(*put_args)
                end = now()
                put.seconds += end - start
                start = end
                if status > WARNING:
                    self._failed(put, status)
            status = step.function(*step_args)
            end = now()
            step.seconds += end - start
            if status > WARNING:
                self._failed(step, status, time + step_size)
            if get is not None:
                start = end
                status = get.function(*get_args)
                get.seconds += now() - start
                if status > WARNING:
                    self._failed(get, status)
        self.steps += 1
        return self.outputs.copy()

    def sync(self) -> None:
        """Add the calls of the steps taken whole since the last sync to each FMU's
        counters (and set each FMU's time to the last step's start)."""
        taken, self._counted = self.steps - self._counted, self.steps
        for subsystem, calls in self._fused:
            subsystem.time = self._at
            for call in calls:
                call.calls += taken

    def _failed(self, call, status: int, end: float | None = None) -> None:
        """A fused call returned Discard or worse: its FMU's check raises the error (the
        calls of this step made so far counted), or keeps a step the FMU ended the
        simulation in (the next step raises :class:`Terminated`)."""
        subsystem = call.owner
        subsystem.time = self._at
        try:
            call.check(status, end)
        except BaseException:
            self.sync()
            for fused, calls in self._fused:
                for made in calls:
                    made.calls += 1
                    if made is call:
                        raise
            raise
        if subsystem.ended_at is not None:
            self._ended = subsystem
