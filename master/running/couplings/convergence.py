"""Convergence tests: when the Newton iteration on the joint forces may stop (a
registry; ``convergence=`` names one).

Each takes the residual R (one entry per joint dof, in the units of the joint's
measure), its tolerance per dof, the held factor of the gluing matrix dR/dF (None
before the first one) and that matrix's diagonal (each dof's own compliance, None
likewise), and returns how far the step is from converged: at most 1 is converged.

* ``residual`` (the default, the seed's test): max |R| / tolerance.
* ``forces``: that, and the joint forces too.  The correction Newton would still
  make, dF = Lambda R, times each dof's own compliance (dR_r/dF_r) must be within
  the tolerance: the residual the correction would remove if it acted on its own dof
  alone.  Where the gluing matrix is well conditioned the two tests agree; near a
  singular configuration of a mechanism (a four bar's links collinear), the joint
  forces along the direction the mechanism hardly moves change the residual by almost
  nothing, and a residual within the tolerance can hide a force error of many times
  what the same tolerance means elsewhere.  This test sees it: one back-substitution
  with the held factor, no FMU call.  It needs a Lambda close to the step's own (the
  ``step`` refresh policy): a stale one misjudges the correction along those directions.
"""
from __future__ import annotations

import numpy as np


def residual(r, tolerance, factor, compliance) -> float:
    """max |R| / tolerance."""
    return float(np.max(np.abs(r) / tolerance, initial=0.0))


def forces(r, tolerance, factor, compliance) -> float:
    """The residual's ratio and the remaining force correction's (see module docstring)."""
    ratio = residual(r, tolerance, factor, compliance)
    if factor is None or compliance is None or not len(r):
        return ratio
    correction = factor.solve(r)
    return max(ratio, float(np.max(np.abs(correction) * np.abs(compliance) / tolerance)))


CONVERGENCE_TESTS = {"residual": residual, "forces": forces}


def what_is_left(r, tolerance, factor, compliance) -> tuple[int, str]:
    """The dof furthest from converged after the last iteration and what is left there
    (for the failure message): its residual, or, when every residual is within the
    tolerance (the forces test is what failed), its remaining force correction."""
    if factor is None or np.any(np.abs(r) > tolerance):
        worst = int(np.argmax(np.abs(r) - tolerance))
        return worst, f"residual {abs(r[worst]):.3e} > tolerance {tolerance[worst]:.3e}"
    correction = np.abs(factor.solve(r)) * np.abs(compliance)
    worst = int(np.argmax(correction / tolerance))
    return worst, (f"residual within the tolerance, but Newton would still change its force "
                   f"by a correction worth {correction[worst]:.3e} of its own dof > "
                   f"tolerance {tolerance[worst]:.3e}")
