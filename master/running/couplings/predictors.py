"""Predictors: the first guess of a macro step's joint forces from past converged
forces (a registry; ``predictor=`` names one).

Each takes the history of converged force vectors (oldest first, at most three)
and the number of joint dofs, and returns a new vector (N, N.m).
"""
from __future__ import annotations

import numpy as np


def zero(history, size: int) -> np.ndarray:
    """No guess: zero forces."""
    return np.zeros(size)


def constant(history, size: int) -> np.ndarray:
    """The last converged forces."""
    return history[-1].copy() if history else np.zeros(size)


def linear(history, size: int) -> np.ndarray:
    """Linear extrapolation of the last two steps (constant with one)."""
    if len(history) < 2:
        return constant(history, size)
    return 2.0 * history[-1] - history[-2]


def quadratic(history, size: int) -> np.ndarray:
    """Quadratic extrapolation of the last three steps (linear with two)."""
    if len(history) < 3:
        return linear(history, size)
    return 3.0 * history[-1] - 3.0 * history[-2] + history[-3]


PREDICTORS = {"none": zero, "constant": constant, "linear": linear, "quadratic": quadratic}
