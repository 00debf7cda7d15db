"""When a physics core's Newton iteration may stop: tests that round-off cannot defeat.

A fixed test on the increment alone fails on some CPUs and not on others: near a
singular configuration the Newton matrix amplifies the last bits of the residual
(which differ with the BLAS kernel numpy picks at run time) into increments that
never fall under the tolerance, although the residual can get no smaller.  Every
core's loop therefore stops on whichever comes first:

* ``"increment"``: the increment is within the relative tolerance of the unknowns
  (plus the round-off floor of its rows); the usual, quadratic ending;
* ``"round-off"``: the residual, row by row, is within ``ROUNDOFF_ULPS`` units in
  the last place of the size of the terms it is made of.  No Newton step can make
  it smaller: the solution is as good as double precision allows.  Counted apart
  (``roundoff_steps``), because it is what a singular configuration looks like.

A step that meets neither within the iteration limit fails as before, and
:func:`failure_message` says whether the Newton matrix was near-singular (the step
is ill-posed there, not merely slow).
"""
from __future__ import annotations

import numpy as np

EPS = float(np.finfo(float).eps)
#: a residual row within this many ulps of the size of its terms is round-off: the
#: terms of a row are summed with a few dozen operations at most, each adding half
#: an ulp of the largest term, so 64 leaves room and is still 1e-14 of the terms
ROUNDOFF_ULPS = 64.0
#: a Newton matrix with a reciprocal condition number below this is near-singular
#: (the increments carry round-off amplified by more than 1e8)
NEAR_SINGULAR_RCOND = 1e-8


def roundoff_floor(scale) -> np.ndarray:
    """The round-off floor of residual rows whose terms have size ``scale`` (same
    units as the residual): ``ROUNDOFF_ULPS`` ulps of it."""
    return ROUNDOFF_ULPS * EPS * np.asarray(scale, dtype=float)


def at_roundoff(residual, scale) -> bool:
    """Whether every row of ``residual`` is within the round-off floor of ``scale``
    (the size of the terms each row sums; an array or one number)."""
    residual = np.abs(np.asarray(residual, dtype=float))
    return bool(np.all(residual <= roundoff_floor(scale)))


class NewtonCount:
    """How a core's Newton solves ended over a run: steps, and steps that ended on
    the round-off test (the residual could get no smaller) rather than the increment."""

    def __init__(self):
        self.roundoff_steps = 0

    def ended(self, how: str) -> None:
        """Record one converged solve (``how`` is ``"increment"`` or ``"round-off"``)."""
        self.roundoff_steps += how == "round-off"


def failure_message(what: str, time: float, iterations: int, increment, jacobian=None,
                    residual=None, scale=None) -> str:
    """The message of a Newton solve that did not converge at ``time`` (s): the last
    increment, the residual against its round-off floor, and, when the Newton
    matrix was near-singular, that a singular configuration makes the step ill-posed."""
    text = (f"{what} did not converge at t = {time:.9g} s after {iterations} iterations "
            f"(last increment {np.max(np.abs(increment), initial=0.0):.3g}")
    if residual is not None and scale is not None:
        ratio = np.max(np.abs(residual) / np.maximum(roundoff_floor(scale), 1e-300),
                       initial=0.0)
        text += f", residual {ratio:.3g} times its round-off floor"
    text += ")"
    if jacobian is not None:
        rcond = reciprocal_condition(jacobian)
        if rcond < NEAR_SINGULAR_RCOND:
            text += (f"; the Newton matrix is near-singular (reciprocal condition "
                     f"{rcond:.2g}): a singular configuration makes this step ill-posed")
    return text


def reciprocal_condition(matrix) -> float:
    """1 / cond_2(matrix) (0 for a singular or non-finite one)."""
    matrix = np.asarray(matrix, dtype=float)
    if matrix.size == 0:
        return 1.0
    if not np.all(np.isfinite(matrix)):
        return 0.0
    sigma = np.linalg.svd(matrix, compute_uv=False)
    return float(sigma[-1] / sigma[0]) if sigma[0] > 0 else 0.0
