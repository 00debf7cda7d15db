"""Closed forms of the C test models (third_party/kinds): the bouncing ball's height, and
the two-mass oscillator split in two FMUs (mass1, mass2) with the connections that join
them."""
import numpy as np
from scipy.linalg import expm

#: the oscillator's connections: mass1 gives x1 and v1, mass2 gives the force back
LINKS = [("mass1", "x1", "mass2", "x1"), ("mass1", "v1", "mass2", "v1"),
         ("mass2", "F", "mass1", "F")]


def exact_x1(times, damping=0.0) -> np.ndarray:
    """mass1's position, closed form: m1 = m2 = 1 kg, k1 = k2 = 10 N/m, coupling
    spring 100 N/m, x1(0) = 0.1 m, at rest; ``damping`` d1 (N.s/m) on mass1."""
    system = np.array([[0, 1, 0, 0], [-110, -damping, 100, 0], [0, 0, 0, 1],
                       [100, 0, -110, 0]])
    return np.array([(expm(system * t) @ [0.1, 0, 0, 0])[0] for t in times])


def bouncing_height(t, g=9.81, e=0.7, h0=1.0):
    """The bouncing ball's height, closed form (flight times scale by e)."""
    first = np.sqrt(2 * h0 / g)
    result = np.empty_like(t)
    for i, tt in enumerate(t):
        if tt < first:
            result[i] = h0 - g * tt * tt / 2
            continue
        start, speed = first, e * g * first
        while tt >= start + 2 * speed / g:
            start, speed = start + 2 * speed / g, speed * e
        s = tt - start
        result[i] = speed * s - g * s * s / 2
    return result
