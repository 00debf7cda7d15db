"""The FlexibleLink2D FMU's model class: FMI 2.0 co-simulation slave of
:class:`fmus.flexible_link.core.FlexibleLink` (pythonfmu), an Euler-Bernoulli beam in a
floating frame (Partitioned Iteration Method), which the FMU's script
:mod:`fmus.flexible_link.flexible_link_fmu` imports.

Parameters: the beam (``length`` m, ``density`` kg/m^3, ``area`` m^2, ``young``
Pa, ``second_moment`` m^4, ``elements``, ``stiffness_damping`` s), its initial CG
pose and rates (``x0 y0 theta0 vx0 vy0 omega0``), gravity and the PIM tolerance.
The defaults are the seed's coupler (6 m, steel 0.1 x 0.1, 6 elements) lying
on the x axis from 3 to 9 m.  Ports A (end at -L/2) and B (+L/2), dofs x y.
Outputs: the reference frame's ``reference.x y theta vx vy omega alpha`` (and
``omega``, the same angular velocity, named as in the rigid Linkage2D FMU),
``deflection``, ``stretch``, ``mean_axis_violation``, ``pim_iterations``.
The variables are declared once for the class (:class:`fmus.fmi_binding.Variable`), not
registered by each instance.
"""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real

from ..fmi_binding import CoreBinding, Variable, glued_slave, port_variables
from .core import FlexibleLink

PARAMETERS = {  # name -> (default, description); keyword of FlexibleLink
    "length": (6.0, "length, m"), "density": (7850.0, "density, kg/m^3"),
    "area": (0.01, "section area, m^2"), "young": (210e9, "Young's modulus, Pa"),
    "second_moment": (0.1 ** 4 / 12.0, "second moment of area, m^4"),
    "stiffness_damping": (0.0, "Rayleigh stiffness damping beta, s"),
    "x0": (6.0, "initial CG x, m"), "y0": (0.0, "initial CG y, m"),
    "theta0": (0.0, "initial angle, rad"), "vx0": (0.0, "initial CG vx, m/s"),
    "vy0": (0.0, "initial CG vy, m/s"), "omega0": (0.0, "initial angular velocity, rad/s"),
    "gravity_x": (0.0, "gravity x, m/s^2"), "gravity_y": (0.0, "gravity y, m/s^2"),
    "tolerance": (1e-10, "PIM relative tolerance"),
}
OUTPUTS = ("reference.x", "reference.y", "reference.theta", "reference.vx", "reference.vy",
           "reference.omega", "reference.alpha", "omega", "deflection", "stretch",
           "mean_axis_violation", "pim_iterations")
#: ports A (end at -L/2) and B (+L/2), dofs x y
INTERFACE = (("A", "x"), ("A", "y"), ("B", "x"), ("B", "y"))


def _parameters() -> list[Variable]:
    """The parameters, in the order of their value references: every Real of
    :data:`PARAMETERS`, then the Integer ``elements``."""
    parameter = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
    variables = [Variable(
        Real, name, description=text,
        get=lambda slave, name=name: slave.values[name],
        set=lambda slave, value, name=name: slave.values.__setitem__(name, float(value)),
        **parameter) for name, (_, text) in PARAMETERS.items()]
    variables.append(Variable(
        Integer, "elements", description="number of beam elements",
        get=lambda slave: slave.elements,
        set=lambda slave, value: setattr(slave, "elements", int(value)), **parameter))
    return variables


@glued_slave
class FlexibleLink2D(Fmi2Slave):
    """A flexible planar link glueable at its ends A and B."""

    author = "dsim"
    description = "Euler-Bernoulli link in a floating frame (PIM, trapezoidal rule)"
    variables = (*_parameters(), *port_variables(INTERFACE, OUTPUTS))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.values = {name: default for name, (default, _) in PARAMETERS.items()}
        self.elements = 6
        self.binding = CoreBinding(self, INTERFACE, OUTPUTS)

    def build_core(self):
        v = self.values
        return _Link(length=v["length"], density=v["density"], area=v["area"],
                     young=v["young"], second_moment=v["second_moment"],
                     elements=self.elements, x=v["x0"], y=v["y0"], theta=v["theta0"],
                     vx=v["vx0"], vy=v["vy0"], omega=v["omega0"],
                     gravity=(v["gravity_x"], v["gravity_y"]),
                     stiffness_damping=v["stiffness_damping"], tolerance=v["tolerance"])


class _Link(FlexibleLink):
    """FlexibleLink with the ``omega`` output alias."""

    def outputs(self):
        out = super().outputs()
        out["omega"] = out["reference.omega"]
        return out
