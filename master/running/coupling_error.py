"""The coupling error of a fixed-step run, estimated as it runs at no FMU call: how far
each connected value moves within a step while its receiver does not see it move.

A connection exchanged once per step (the causal coupling, and the iterative one for what
is not in a joint) hands its receiver the source's value at the step's start and holds it
over the step: the input is off by up to the source's change over the step, ``|u_n -
u_(n-1)|``, the first difference.  A connection the strong coupling iterates ends the
step at the source's own value and ramps (or holds the end value) in between: what is
left is of second order, estimated by the second difference ``|u_n - 2 u_(n-1) + u_(n-2)|
/ 8`` (the error of a linear ramp at its middle).  Each connection's largest estimate is
given relative to its source's range over the run; where one passes
:data:`WARN_FRACTION` the run says so once, naming the connections and the remedies.
"""
from __future__ import annotations

import numpy as np

#: a connection whose estimate passes this fraction of its source's range is named: on the
#: two-mass oscillator (tests/running/test_coupling_error.py) 0.72 % per step left the causal run
#: 50 % off its closed form after 10 s, 0.13 % left the strong one 4.6 % off, 0.0013 % 0.05 %
WARN_FRACTION = 1e-3
#: connections named one by one in the warning
NAMED = 5


#: steps gathered before they are looked at together (one numpy pass per block: a pass
#: per step cost 10 us a step, 60 % of a causal step of two small C FMUs)
BLOCK = 512


class CouplingErrorWatch:
    """Follows the connected sources (``sources``: their indices in the coupling's
    flat outputs, ``labels`` their names, ``iterated``: whether the strong coupling
    iterates each) from step to step."""

    #: what a checkpoint keeps (:mod:`dsim.master.running.checkpointing`)
    CHECKPOINTED = ("_largest", "_low", "_high", "_pending", "_tail")

    def __init__(self, sources, labels, iterated):
        self.sources = np.asarray(sources, dtype=int)
        self.labels = tuple(labels)
        self._iterated = np.asarray(iterated, dtype=bool)
        n = len(self.sources)
        self._largest = np.zeros(n)
        self._low, self._high = np.full(n, np.inf), np.full(n, -np.inf)
        self._pending: list = []  # the outputs of the steps not looked at yet
        self._tail = np.zeros((0, n))  # the last two points looked at (for differences)

    def add(self, outputs: np.ndarray) -> None:
        """The outputs at the next communication point (the start point first): an
        array the caller does not change afterwards (each step's is a new one)."""
        self._pending.append(outputs)
        if len(self._pending) >= BLOCK:
            self._look()

    def _look(self) -> None:
        """Take the pending points into the estimate."""
        if not self._pending:
            return
        block = np.stack(self._pending)[:, self.sources]
        self._pending = []
        np.minimum(self._low, block.min(axis=0), out=self._low)
        np.maximum(self._high, block.max(axis=0), out=self._high)
        values = np.concatenate((self._tail, block))
        self._tail = values[-2:]
        if len(values) < 2:
            return
        first = np.abs(np.diff(values, axis=0)).max(axis=0)
        if self._iterated.any():
            second = np.abs(np.diff(values, 2, axis=0)).max(axis=0) / 8.0 \
                if len(values) >= 3 else np.zeros_like(first)
            first = np.where(self._iterated, second, first)
        np.maximum(self._largest, first, out=self._largest)

    def relative(self) -> np.ndarray:
        """Each connection's largest estimate over its source's range (0 where the
        source never moved)."""
        self._look()
        span = self._high - self._low
        scale = np.maximum(span, 1e-6 * np.maximum(np.abs(self._high), np.abs(self._low)))
        with np.errstate(all="ignore"):
            ratio = np.where(scale > 0, self._largest / scale, 0.0)
        return np.where(np.isfinite(ratio), ratio, 0.0)

    def statistics(self) -> dict:
        """The largest estimate relative to its source's range, which connection, and
        every connection's (the statistics' ``coupling_error``)."""
        ratio = self.relative()
        if not len(ratio):
            return {"largest": 0.0, "connection": None, "per_connection": {}}
        worst = int(np.argmax(ratio))
        return {"largest": float(ratio[worst]), "connection": self.labels[worst],
                "per_connection": {label: float(r) for label, r in zip(self.labels, ratio)}}

    def warning(self, coupling: str) -> str | None:
        """One line when a connection's estimate passes :data:`WARN_FRACTION` of its
        range: which connections, by how much, and what reduces it; else None."""
        ratio = self.relative()
        over = [i for i in np.argsort(-ratio) if ratio[i] > WARN_FRACTION]
        if not over:
            return None
        named = ", ".join(f"{self.labels[i]} ({100 * ratio[i]:.2g} %)" for i in over[:NAMED])
        more = f" and {len(over) - NAMED} more" if len(over) > NAMED else ""
        if coupling == "strong":
            how = ("bend that much of their range within one step beyond the straight "
                   "line the FMUs they feed are given")
            remedy = "--step auto or a smaller --step reduces it"
        else:
            how = ("change that much of their range within one step while the FMUs they "
                   "feed hold the step's start value")
            remedy = ("--coupling strong (the connections iterated; an FMU that cannot "
                      "roll back in co-simulation through its Model Exchange interface), "
                      "--step auto or a smaller --step reduces it")
        return (f"the coupling error may be large: connected values {named}{more} {how} "
                f"({coupling} coupling); {remedy} (statistics: coupling_error)")
