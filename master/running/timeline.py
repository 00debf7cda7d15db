"""Communication points and the step sizes handed to the FMUs.

The master's times are computed (``start + n * step``, the last one the stop time),
never summed.  An FMU, though, sums: it ends a step at ``t + h`` in its own double
arithmetic, and some FMUs refuse a step that ends past the stop time of
fmi2SetupExperiment by any amount (``Exceeded model finish time: 0.01 > 0.01``: the
tenth step of 0.001 s from 0.009000000000000001 ends at 0.010000000000000002).  So the
step size handed over is chosen for where the FMU's own sum lands:
every step but the last is the nominal step (an FMU's sum ends within an ulp of
the next point, far from the stop time); the last one is :func:`size_to` the stop
time: the largest size whose sum lands on it, never past it.  A size that differs
from the nominal one by round-off only (:func:`same_size`) keeps what is keyed to
the step size (the interface flexibility).
"""
from __future__ import annotations

import math

#: step sizes closer than this (relative) differ by round-off only
ROUNDOFF = 1e-9


def same_size(a: float, b: float) -> bool:
    """Whether step sizes ``a`` and ``b`` differ by round-off only."""
    return abs(a - b) <= ROUNDOFF * max(abs(a), abs(b))


def size_to(start: float, end: float, nominal: float | None = None) -> float:
    """The step size an FMU at ``start`` is handed to end at ``end``: ``nominal``
    when the FMU's sum ``start + nominal`` is ``end``; else ``end - start``, made
    smaller by an ulp at a time until ``start + size`` is not past ``end``."""
    if nominal is not None and start + nominal == end:
        return nominal
    size = end - start
    while size > 0 and start + size > end:
        size = math.nextafter(size, 0.0)
    return size


def step_count(start: float, stop: float, step: float) -> int:
    """Macro steps from ``start`` to ``stop``: the whole number of steps when the span
    is one up to round-off, else one more than fit (the last one shorter)."""
    ratio = (stop - start) / step
    whole = round(ratio)
    if whole >= 1 and abs(ratio - whole) <= ROUNDOFF * max(ratio, 1.0):
        return whole
    return max(1, math.ceil(ratio))


def is_whole(start: float, stop: float, step: float) -> bool:
    """Whether ``start`` .. ``stop`` is a whole number of ``step`` (up to round-off):
    else the last step is shorter, which only an FMU that accepts variable steps takes."""
    ratio = (stop - start) / step
    return abs(ratio - round(ratio)) <= ROUNDOFF * max(ratio, 1.0)


def span_note(start: float, stop: float, step: float) -> str | None:
    """What a run from ``start`` to ``stop`` (s) in macro steps of ``step`` (s) actually
    does when the step does not fit the span (a step longer than the span, or one
    that does not divide it: the last step is shorter), in one sentence; None when
    the span is a whole number of steps."""
    if not (math.isfinite(start) and math.isfinite(stop) and math.isfinite(step)) or \
            step <= 0 or stop <= start:
        return None  # check_span and the settings' checks refuse these
    span = stop - start
    if step > span and not same_size(step, span):
        return (f"step {step:g} s is longer than the span {start:g} .. {stop:g} s: the run "
                f"takes one step of {span:g} s")
    if is_whole(start, stop, step):
        return None
    count = step_count(start, stop, step)
    last = span - (count - 1) * step
    return (f"step {step:g} s does not divide the span {start:g} .. {stop:g} s: the run "
            f"takes {count - 1} step{'s' * (count > 2)} of {step:g} s and a last one of "
            f"{last:.6g} s")


def halves(start: float, size: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """The two halves of the step of ``size`` from ``start`` (a cut step), each as
    (start, size): the second ends where the whole would in the FMUs' sum
    (``start + size``), never past it: a cut last step still ends at the stop time."""
    half = 0.5 * size
    middle = start + half
    return (start, half), (middle, size_to(middle, start + size, half))
