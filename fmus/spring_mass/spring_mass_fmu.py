"""FMI 2.0 co-simulation wrapper of :class:`fmus.spring_mass.core.SpringMassChain`.

Every model quantity is a parameter (``n``, ``m[i]``, ``k[i]``, ..., ``P.mass``), so
one FMU serves every spring-mass scene; outputs ``x[i]``, ``v[i]``, ``a[i]`` and the
port variables of DESIGN.md.  The FMU state is the chain's complete numerical state.
"""
import os
import sys

# Another dsim FMU in this process may have imported the fmus package from its own
# resources folder, which its master may since have deleted: look in ours first.
_OWN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fmus")
if "fmus" in sys.modules and os.path.isdir(_OWN) and _OWN not in sys.modules["fmus"].__path__:
    sys.modules["fmus"].__path__.insert(0, _OWN)

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

from fmus.fmi_binding import CoreBinding, glued_slave
from fmus.spring_mass.core import MAX_MASSES, ChainParameters, SpringMassChain

DESCRIPTIONS = {
    "m": "mass, kg", "k_ground": "spring to ground k0, N/m",
    "k1_ground": "spring to ground k1 (eq. 5.36), N/m^2",
    "c_ground": "damper to ground c0, N.s/m", "c1_ground": "damper to ground c1, N.s^2/m^2",
    "k": "spring to next mass k0, N/m", "k1": "spring to next mass k1, N/m^2",
    "c": "damper to next mass c0, N.s/m", "c1": "damper to next mass c1, N.s^2/m^2",
    "F0": "constant load, N", "Fa": "sine load amplitude, N", "omega": "sine load frequency, rad/s",
    "phase": "sine load phase, rad", "x0": "initial position, m", "v0": "initial velocity, m/s",
    "bump": "half-sine bump of the ground under the mass: height, m",
    "bump_start": "half-sine bump: start time, s",
    "bump_duration": "half-sine bump: duration, s (0: no bump)",
}


@glued_slave
class SpringMass(Fmi2Slave):
    """A chain of up to four masses with linear or nonlinear springs and dampers."""

    author = "dsim"
    description = "Spring-mass chain (trapezoidal rule), glueable at ports P and Q"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.params = ChainParameters()
        parameter = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        self.register_variable(Integer(
            "n", description=f"number of masses, 1 to {MAX_MASSES}",
            getter=lambda: self.params.n,
            setter=lambda value: setattr(self.params, "n", int(value)), **parameter))
        for port in ("P", "Q"):
            attribute = f"port_{port}"
            self.register_variable(Integer(
                f"{port}.mass", description=f"mass (1-based) that port {port} sits on",
                getter=lambda a=attribute: getattr(self.params, a),
                setter=lambda value, a=attribute: setattr(self.params, a, int(value)),
                **parameter), nested=False)
        for name in ChainParameters.array_names():
            for i in range(MAX_MASSES):
                self.register_variable(Real(
                    f"{name}[{i + 1}]", description=DESCRIPTIONS[name],
                    getter=lambda name=name, i=i: float(getattr(self.params, name)[i]),
                    setter=lambda value, name=name, i=i: self._set(name, i, value),
                    **parameter), nested=False)
        outputs = [f"{q}[{i + 1}]" for q in ("x", "v", "a") for i in range(MAX_MASSES)]
        self.binding = CoreBinding(self, SpringMassChain.interface, outputs)

    def _set(self, name, index, value):
        getattr(self.params, name)[index] = float(value)

    def build_core(self):
        return SpringMassChain(self.params)
