"""The generalized-alpha rule of the planar cores, with the trapezoidal rule as its
undamped member (no FMI; any units, SI in the cores).

Chung & Hulbert (1993), in the form of Arnold & Bruls (2007) for constrained
mechanical systems: the equations of motion and the constraints hold at t + h with
the true acceleration qdd, and a separate *pseudo-acceleration* p carries the
numerical damping:

    (1 - alpha_m) p1 + alpha_m p  =  (1 - alpha_f) qdd1 + alpha_f qdd
    q1 = q + h v + h^2 (1/2 - beta) p + h^2 beta p1
    v1 = v + h (1 - gamma) p + h gamma p1

with alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 + alpha_f
- alpha_m, beta = (gamma + 1/2)^2 / 4 for a spectral radius at infinite frequency
rho (0 <= rho <= 1).  Second order; modes far above 1/h are damped by rho per step,
the resolved ones hardly at all.  Why the cores need it: on position-level (index-3)
constraint rows, and on fixed glue joints of the displacement measure, which are such
rows, the trapezoidal rule leaves the multipliers an undamped period-2 mode
(eigenvalue -1); rho < 1 damps it (docs/linkages.md measures it on the four bar).

Because equilibrium holds at t + h with the forces held over the step, the rule keeps
the gluing contract of fmus/interface.py (a step satisfies equilibrium at t + h under
the held interface forces): a glued mechanism whose parts all use it solves the
discrete equations of the whole mechanism under the same rule.

rho = 1 gives alpha_m = alpha_f = 1/2, gamma = 1/2, beta = 1/4 and p = qdd at every
step (when started with p = qdd): the trapezoidal rule.  :class:`GeneralizedAlpha`
then does the trapezoidal arithmetic itself, operation for operation as the cores
always did, so a default run keeps its numbers to the last bit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: the trapezoidal rule (no numerical damping): the cores' default
TRAPEZOIDAL = 1.0


@dataclass(frozen=True)
class GeneralizedAlpha:
    """Coefficients and update formulas of the rule for spectral radius ``rho``."""

    rho: float = TRAPEZOIDAL
    alpha_m: float = field(init=False)
    alpha_f: float = field(init=False)
    gamma: float = field(init=False)
    beta: float = field(init=False)

    def __post_init__(self):
        rho = float(self.rho)
        if not 0.0 <= rho <= 1.0:
            raise ValueError(f"spectral radius rho_inf must be in [0, 1], not {rho:g}")
        alpha_m = (2.0 * rho - 1.0) / (rho + 1.0)
        alpha_f = rho / (rho + 1.0)
        gamma = 0.5 + alpha_f - alpha_m
        object.__setattr__(self, "rho", rho)
        object.__setattr__(self, "alpha_m", alpha_m)
        object.__setattr__(self, "alpha_f", alpha_f)
        object.__setattr__(self, "gamma", gamma)
        object.__setattr__(self, "beta", 0.25 * (gamma + 0.5) ** 2)

    @property
    def trapezoidal(self) -> bool:
        """Whether this is the undamped member (rho = 1), the trapezoidal rule."""
        return self.rho == TRAPEZOIDAL

    @property
    def position_weight(self) -> float:
        """d q1 / d qdd1 divided by h^2 (1/4 for the trapezoidal rule)."""
        return self.beta * (1.0 - self.alpha_f) / (1.0 - self.alpha_m)

    @property
    def velocity_weight(self) -> float:
        """d v1 / d qdd1 divided by h (1/2 for the trapezoidal rule)."""
        return self.gamma * (1.0 - self.alpha_f) / (1.0 - self.alpha_m)

    def predict(self, q, v, a, p, h: float):
        """The parts of q1 and v1 that do not depend on qdd1: q1 = q_pred +
        position_weight h^2 qdd1, v1 = v_pred + velocity_weight h qdd1, from the
        start state (q, v, qdd = ``a``, pseudo-acceleration ``p``) and step ``h``."""
        if self.trapezoidal:  # the cores' trapezoidal arithmetic, bit for bit
            return q + h * v + 0.25 * h * h * a, v + 0.5 * h * a
        known = (self.alpha_f * a - self.alpha_m * p) / (1.0 - self.alpha_m)
        q_pred = q + h * v + h * h * ((0.5 - self.beta) * p + self.beta * known)
        v_pred = v + h * ((1.0 - self.gamma) * p + self.gamma * known)
        return q_pred, v_pred

    def pseudo(self, a, p, a1):
        """The pseudo-acceleration at t + h from qdd (``a``), p at t and qdd1 (``a1``)."""
        if self.trapezoidal:
            return np.array(a1, copy=True)
        return (self.alpha_f * a - self.alpha_m * p + (1.0 - self.alpha_f) * a1) / (
            1.0 - self.alpha_m)
