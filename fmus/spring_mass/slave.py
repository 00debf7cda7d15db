"""The SpringMass FMU's model class: FMI 2.0 co-simulation slave of
:class:`fmus.spring_mass.core.SpringMassChain` (pythonfmu), which the FMU's script
:mod:`fmus.spring_mass.spring_mass_fmu` imports.

Every model quantity is a parameter (``n``, ``m[i]``, ``k[i]``, ..., ``P.mass``), so
one FMU serves every spring-mass scene; outputs ``x[i]``, ``v[i]``, ``a[i]`` and the
port variables of DESIGN.md.  The FMU state is the chain's complete numerical state.
The variables are declared once for the class (:class:`fmus.fmi_binding.Variable`), not
registered by each instance: a scene may hold ten thousand SpringMass instances.
"""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

from ..fmi_binding import CoreBinding, Variable, glued_slave, port_variables
from .core import MAX_MASSES, ChainParameters, SpringMassChain

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


#: the outputs besides the port variables: x[i], v[i], a[i] of every mass
OUTPUTS = tuple(f"{q}[{i + 1}]" for q in ("x", "v", "a") for i in range(MAX_MASSES))


def _parameters() -> list[Variable]:
    """The parameters, in the order of their value references: n, P.mass, Q.mass, then
    every per-mass array (m[1] ... m[4], k_ground[1] ...)."""
    parameter = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
    variables = [Variable(
        Integer, "n", description=f"number of masses, 1 to {MAX_MASSES}",
        get=lambda slave: slave.params.n,
        set=lambda slave, value: setattr(slave.params, "n", int(value)), **parameter)]
    for port in ("P", "Q"):
        attribute = f"port_{port}"
        variables.append(Variable(
            Integer, f"{port}.mass", description=f"mass (1-based) that port {port} sits on",
            get=lambda slave, a=attribute: getattr(slave.params, a),
            set=lambda slave, value, a=attribute: setattr(slave.params, a, int(value)),
            **parameter))
    for name in ChainParameters.array_names():
        for i in range(MAX_MASSES):
            variables.append(Variable(
                Real, f"{name}[{i + 1}]", description=DESCRIPTIONS[name],
                get=lambda slave, name=name, i=i: float(getattr(slave.params, name)[i]),
                set=lambda slave, value, name=name, i=i: slave._set(name, i, value),
                **parameter))
    return variables


@glued_slave
class SpringMass(Fmi2Slave):
    """A chain of up to four masses with linear or nonlinear springs and dampers."""

    author = "dsim"
    description = "Spring-mass chain (trapezoidal rule), glueable at ports P and Q"
    variables = (*_parameters(), *port_variables(SpringMassChain.interface, OUTPUTS))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.params = ChainParameters()
        self.binding = CoreBinding(self, SpringMassChain.interface, OUTPUTS)

    def _set(self, name, index, value):
        getattr(self.params, name)[index] = float(value)

    def build_core(self):
        return SpringMassChain(self.params)
