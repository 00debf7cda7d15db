"""Real inputs extrapolated over the substeps of a macro step (``--substeps``) for an
FMI 2.0 co-simulation FMU that declares ``canInterpolateInputs``.

A causal master knows, at the start ``t`` of a macro step, the inputs' present values
``u(t)`` and, from the step before, ``u(t0)``; nothing later.  The first-order choice it
has is to extrapolate with the slope ``(u(t) - u(t0)) / (t - t0)`` (as libcosim and
MasterSim do with input derivatives): at the start ``t_k`` of every substep the FMU is
given the values on that line, ``u(t) + slope (t_k - t)`` (``fmi2SetReal``), and the
slope (``fmi2SetRealInputDerivatives``, order 1), with which it interpolates within
the substep itself.  Both are set again at every substep: FMI 2.0 relates inputs and
their derivatives to the start of a communication step, so an FMU that keeps a slope
over later steps and one that forgets it at the next step see the same line.  At the
first macro step there is no earlier value: the slope is zero (the inputs held).

A macro step taken again from its start, or from an earlier time (a rejected step of
the error control, a rollback), extrapolates from the values before that time, never
from those of the step given up.
"""
from __future__ import annotations

import ctypes

import numpy as np

#: how many (time, values) pairs are kept: enough to go back over a rejected step
KEPT = 4


def extrapolated_places(variables: dict, writes) -> list[int]:
    """Where, among the connected inputs ``writes`` (names, in the subsystem's order),
    are those extrapolated: continuous Real inputs (``variables``: name -> the FMU's
    variable)."""
    return [i for i, name in enumerate(writes) if variables[name].type == "Real"
            and variables[name].causality == "input"
            and variables[name].variability == "continuous"]


class InputSlopes:
    """The Real inputs of one FMU written at the start of each macro step, and what to
    set at each substep.  ``places``: where they are in the subsystem's written values
    (``spec.writes`` order); ``references``: the fmi2ValueReference array and its
    count; ``set_real``, ``set_derivatives``: the owner's bound ``fmi2SetReal`` and
    ``fmi2SetRealInputDerivatives`` calls (counted, timed, checked)."""

    def __init__(self, places, references, set_real, set_derivatives):
        self.places = np.asarray(places, dtype=int)
        self.count, self.vrs = references
        size = len(self.places)
        self.values = (ctypes.c_double * size)()
        self.slopes = (ctypes.c_double * size)()
        self.orders = (ctypes.c_int * size)(*([1] * size))
        self.set_real = set_real
        self.set_derivatives = set_derivatives
        #: the last values written (the next macro step's u(t))
        self.written = np.zeros(size)
        #: (time s, values) at the start of the last macro steps, oldest first
        self.history: list[tuple[float, np.ndarray]] = []

    def wrote(self, values) -> None:
        """Note the connected inputs just written (all of them, ``spec.writes`` order)."""
        self.written = np.asarray(values, dtype=float)[self.places]

    def kept(self) -> tuple:
        """What a fresh instance needs to go on extrapolating (:meth:`keep`): the
        values of the last macro steps' starts and the last values written."""
        return [(t, values.copy()) for t, values in self.history], self.written.copy()

    def keep(self, kept: tuple) -> None:
        """Go on from what :meth:`kept` returned (of another instance)."""
        history, written = kept
        self.history = [(t, np.array(values, dtype=float)) for t, values in history]
        self.written = np.array(written, dtype=float)

    def slope(self, time: float) -> np.ndarray:
        """The slope (input units per s) for a macro step from ``time`` (s), from the
        inputs written last and those at the start of the step before (zero at the
        first step); remembers them as the values at ``time``."""
        while self.history and self.history[-1][0] >= time:  # a step taken again
            self.history.pop()
        now = self.written.copy()
        if self.history:
            before, values = self.history[-1]
            slope = (now - values) / (time - before)
        else:
            slope = np.zeros_like(now)
        self.history.append((time, now))
        del self.history[:-KEPT]
        return slope

    def ramp(self, time: float):
        """For a macro step from ``time`` (s): the function of a substep's start time
        (s) that sets the inputs on the extrapolated line there and their slope."""
        slope = self.slope(time)
        start = self.history[-1][1]
        self.slopes[:] = slope

        def at(t: float) -> None:
            if t != time:  # at the step's start the values are those just written
                self.values[:] = start + slope * (t - time)
                self.set_real(self.vrs, self.count, self.values)
            self.set_derivatives(self.vrs, self.count, self.orders, self.slopes)
        return at
