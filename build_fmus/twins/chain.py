"""The monolithic twin of the chain_<n> scenes (n one-mass FMUs glued in a line by
fixed joints): fixed joints make the chain one rigid body, a mass n*m on a spring n*k
to ground under the end load, integrated with the same trapezoidal rule and step;
every mass of the glued chain must follow it (examples/chain.py compares).
"""
from __future__ import annotations

import math

import numpy as np

from dsim.build_fmus.scenes import CHAIN
from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain


def monolithic(n: int, stop: float = CHAIN["stop"], step: float = CHAIN["step"]):
    """Times (s) and the common position (m) of the rigidly glued chain."""
    p = CHAIN
    params = ChainParameters(n=1)
    params.m[0] = n * p["m"]
    params.k_ground[0] = n * p["k"]
    params.Fa[0] = p["Fa"]
    params.omega[0] = 2 * math.pi * p["frequency"]
    count = round(stop / step)
    return np.arange(count + 1) * step, SpringMassChain(params).history(count, step)[:, 0]
