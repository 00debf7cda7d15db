"""The monolithic twin of seed section 5.3.1 (eq. 5.37), the spring_mass_* scenes:
masses m1, m2, m3 in one chain, m1 on a spring k to ground, the joint law between m1
and m2, a spring k between m2 and m3, a constant force F on m3; integrated with the
same trapezoidal rule and step as the glued run.  examples/spring_mass.py compares a
glued run with it.
"""
from __future__ import annotations

import numpy as np

from dsim.build_fmus.scenes import SPRING_MASS
from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain


def monolithic(nonlinear: bool, stop: float = SPRING_MASS["stop"],
               step: float = SPRING_MASS["step"]):
    """Times (s) and positions x1, x2, x3 (m) of the eq. 5.37 model, one row per step."""
    p = SPRING_MASS
    params = ChainParameters(n=3)
    params.m[:3] = p["m"]
    params.k_ground[0] = p["k"]
    params.k[:2] = (p["k0"], p["k"])
    params.c[0] = p["c0"]
    if nonlinear:
        params.k1[0], params.c1[0] = p["k1"], p["c1"]
    params.F0[2] = p["F"]
    count = round(stop / step)
    return np.arange(count + 1) * step, SpringMassChain(params).history(count, step)
