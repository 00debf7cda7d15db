"""FMI 2.0 co-simulation wrapper of :class:`fmus.flexible_link.core.FlexibleLink`:
an Euler-Bernoulli beam in a floating frame (Partitioned Iteration Method).

Parameters: the beam (``length`` m, ``density`` kg/m^3, ``area`` m^2, ``young``
Pa, ``second_moment`` m^4, ``elements``, ``stiffness_damping`` s), its initial CG
pose and rates (``x0 y0 theta0 vx0 vy0 omega0``), gravity and the PIM tolerance.
The defaults are the seed's coupler (6 m, steel 0.1 x 0.1, 6 elements) lying
on the x axis from 3 to 9 m.  Ports A (end at -L/2) and B (+L/2), dofs x y.
Outputs: the reference frame's ``reference.x y theta vx vy omega alpha`` (and
``omega``, the same angular velocity, named as in the rigid Linkage2D FMU),
``deflection``, ``stretch``, ``mean_axis_violation``, ``pim_iterations``.
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
from fmus.flexible_link.core import FlexibleLink

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


@glued_slave
class FlexibleLink2D(Fmi2Slave):
    """A flexible planar link glueable at its ends A and B."""

    author = "dsim"
    description = "Euler-Bernoulli link in a floating frame (PIM, trapezoidal rule)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.values = {name: default for name, (default, _) in PARAMETERS.items()}
        self.elements = 6
        parameter = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        for name, (_, text) in PARAMETERS.items():
            self.register_variable(Real(
                name, description=text, getter=lambda name=name: self.values[name],
                setter=lambda value, name=name: self.values.__setitem__(name, float(value)),
                **parameter), nested=False)
        self.register_variable(Integer(
            "elements", description="number of beam elements",
            getter=lambda: self.elements,
            setter=lambda value: setattr(self, "elements", int(value)), **parameter))
        self.binding = CoreBinding(self, (("A", "x"), ("A", "y"), ("B", "x"), ("B", "y")),
                                   OUTPUTS)

    def build_core(self):
        v = self.values
        core = _Link(length=v["length"], density=v["density"], area=v["area"],
                     young=v["young"], second_moment=v["second_moment"],
                     elements=self.elements, x=v["x0"], y=v["y0"], theta=v["theta0"],
                     vx=v["vx0"], vy=v["vy0"], omega=v["omega0"],
                     gravity=(v["gravity_x"], v["gravity_y"]),
                     stiffness_damping=v["stiffness_damping"], tolerance=v["tolerance"])
        return core


# After the FMU class: pythonfmu's loader takes the first class line of the module.
class _Link(FlexibleLink):
    """FlexibleLink with the ``omega`` output alias."""

    def outputs(self):
        out = super().outputs()
        out["omega"] = out["reference.omega"]
        return out
