"""Telling a diverging run from a hard one, before its values overflow.

Two signs, one per coupling:

* Newton within a step (iterative): the residual grows by ``NEWTON_GROWTH`` over
  its smallest value of the step although the interface flexibility was re-measured
  in that step: a fresh Lambda that still makes things worse is not a stale one, the
  step is too large for the joint's nonlinearity (or the motion has no solution).
* Across steps (explicit): the interface residual's envelope, its largest value
  per block of steps, grows by more than ``GROWTH`` in each of ``BLOCKS`` blocks in
  a row (3^5 = 243), on blocks of 10 to 1000 steps (a fast divergence shows on the
  short blocks within 60 steps, a slow one, a few per mille per step, on the long
  ones; a run of fewer than 60 steps is not judged: shorter blocks called runs from
  rest diverging, whose residual grows fast from nothing in the first steps).  An unstable explicit coupling grows geometrically and oscillates (so
  no per-step rule holds); a stable run from rest grows at most like a power of
  time, whose block ratios (k+1)^p / k^p fall below 3 within five blocks for any p
  below 6.  Measured (benchmarks/stability.py, docs/stability.md): the unstable
  explicit runs are caught long before a value overflows; no stable one is.
"""
from __future__ import annotations

#: growth of the Newton residual over its smallest value in a step, after a refresh
NEWTON_GROWTH = 1e4
#: steps per block (one watch per size), growth per block, blocks in a row (explicit)
BLOCK_SIZES, GROWTH, BLOCKS = (10, 30, 100, 300, 1000), 3.0, 5


def newton_diverging(history, refreshed: int) -> bool:
    """Whether a step's residual history (max |R| / tolerance per iteration) shows
    divergence rather than slow convergence."""
    return bool(refreshed) and len(history) >= 3 and (
        history[-1] > NEWTON_GROWTH * min(history[:-1]))


class _Blocks:
    """The envelope on blocks of one size."""

    #: what a checkpoint keeps (:mod:`dsim.master.running.checkpointing`)
    CHECKPOINTED = ("_count", "_largest", "_maxima", "_growing")

    def __init__(self, size: int):
        self.size = size
        self._count = 0
        self._largest = 0.0
        self._maxima: list[float] = []
        self._growing = 0

    def add(self, residual: float) -> float | None:
        self._largest = max(self._largest, residual)
        self._count += 1
        if self._count < self.size:
            return None
        largest, self._count, self._largest = self._largest, 0, 0.0
        if self._maxima and largest > GROWTH * self._maxima[-1]:
            self._growing += 1
        else:
            self._growing = 0
        self._maxima = (self._maxima + [largest])[-(BLOCKS + 1):]
        return largest / self._maxima[0] if self._growing >= BLOCKS else None


class EnvelopeWatch:
    """The residual's envelope over the steps of an explicit run."""

    CHECKPOINTED = ("_scales", "block")

    def __init__(self):
        self._scales = [_Blocks(size) for size in BLOCK_SIZES]
        #: the block size (steps) on which the last divergence showed
        self.block = 0

    def add(self, residual: float) -> float | None:
        """Record a step's largest residual; the growth of the envelope over the last
        ``BLOCKS`` blocks when it says the run diverges, else None."""
        for scale in self._scales:
            growth = scale.add(residual)
            if growth is not None:
                self.block = scale.size
                return growth
        return None
