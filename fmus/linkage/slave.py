"""The Linkage2D FMU's model class: FMI 2.0 co-simulation slave of a planar linkage
(:class:`fmus.linkage.parts.PartCore` over :class:`fmus.linkage.core.Linkage`, pythonfmu),
which the FMU's script :mod:`fmus.linkage.linkage_fmu` imports.

The String parameter ``mechanism`` describes it (JSON text or a file of the
resources folder: bodies, pins, sliders, drivers, springs, bushings, ports,
gravity; :mod:`fmus.linkage.description`), so one FMU serves any planar linkage
(by default a pendulum, so that it runs alone).  The constraint stabilisation (``formulation``,
``baumgarte_frequency`` w rad/s, ``baumgarte_damping`` xi) is a parameter too, and so is
the integrator's ``spectral_radius`` rho_inf (1, the default: the trapezoidal rule;
below 1: generalized-alpha, which damps the modes above 1/h).  Ports A, B, P (dofs x y)
follow DESIGN.md; a port the part lacks takes no force and reports zero motion.
Outputs: the part's body ``x y theta vx vy omega ax ay alpha``, the driver
``torque``, ``constraint_violation``, ``newton_iterations`` and ``newton_roundoff_steps``.
The variables are declared once for the class (:class:`fmus.fmi_binding.Variable`), not
registered by each instance.
"""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String

from ..fmi_binding import CoreBinding, Variable, glued_slave, port_variables
from .parts import PART_OUTPUTS, PartCore, PartParameters, build_part

DESCRIPTIONS = {
    "mechanism": "the mechanism: a description (JSON text, docs/linkages.md) or the name of "
                 "a file holding one in the FMU's resources folder (default: a pendulum)",
    "formulation": "constraint rows: baumgarte or index3",
    "baumgarte_frequency": "Baumgarte w, rad/s", "baumgarte_damping": "Baumgarte xi",
    "spectral_radius": "rho_inf of the generalized-alpha rule, 0..1: numerical damping of "
                       "the modes above 1/h (1: the trapezoidal rule, no damping)",
}


def _parameters() -> list[Variable]:
    """The parameters, one per field of :class:`PartParameters` in its order (String for
    a text field, else Real), each read from and written to the instance's ``params``."""
    variables = []
    for name, value in vars(PartParameters()).items():
        kind = String if isinstance(value, str) else Real
        variables.append(Variable(
            kind, name, description=DESCRIPTIONS[name], causality=Fmi2Causality.parameter,
            variability=Fmi2Variability.fixed,
            get=lambda slave, name=name: getattr(slave.params, name),
            set=lambda slave, value, name=name, convert=str if kind is String else float:
                setattr(slave.params, name, convert(value))))
    return variables


@glued_slave
class Linkage2D(Fmi2Slave):
    """A planar rigid mechanism from its description, glueable at A, B, P."""

    author = "dsim"
    description = ("Planar rigid multibody part (trapezoidal or generalized-alpha rule, "
                   "Baumgarte rows)")
    variables = (*_parameters(), *port_variables(PartCore.interface, PART_OUTPUTS))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.params = PartParameters()
        self.binding = CoreBinding(self, PartCore.interface, PART_OUTPUTS)

    def build_core(self):
        return PartCore(build_part(self.params, self.resources))
