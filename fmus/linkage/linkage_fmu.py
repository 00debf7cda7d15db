"""FMI 2.0 co-simulation wrapper of a planar linkage
(:class:`fmus.linkage.parts.PartCore` over :class:`fmus.linkage.core.Linkage`).

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
"""
import os
import sys

# Another dsim FMU in this process may have imported the fmus package from its own
# resources folder, which its master may since have deleted: look in ours first.
_OWN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fmus")
if "fmus" in sys.modules and os.path.isdir(_OWN) and _OWN not in sys.modules["fmus"].__path__:
    sys.modules["fmus"].__path__.insert(0, _OWN)

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real, String

from fmus.fmi_binding import CoreBinding, glued_slave
from fmus.linkage.parts import PART_OUTPUTS, PartCore, PartParameters, build_part

DESCRIPTIONS = {
    "mechanism": "the mechanism: a description (JSON text, docs/linkages.md) or the name of "
                 "a file holding one in the FMU's resources folder (default: a pendulum)",
    "formulation": "constraint rows: baumgarte or index3",
    "baumgarte_frequency": "Baumgarte w, rad/s", "baumgarte_damping": "Baumgarte xi",
    "spectral_radius": "rho_inf of the generalized-alpha rule, 0..1: numerical damping of "
                       "the modes above 1/h (1: the trapezoidal rule, no damping)",
}


@glued_slave
class Linkage2D(Fmi2Slave):
    """A planar rigid mechanism from its description, glueable at A, B, P."""

    author = "dsim"
    description = ("Planar rigid multibody part (trapezoidal or generalized-alpha rule, "
                   "Baumgarte rows)")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.params = PartParameters()
        parameter = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)
        for name, value in vars(self.params).items():
            kind = String if isinstance(value, str) else Real
            self.register_variable(kind(
                name, description=DESCRIPTIONS[name],
                getter=lambda name=name: getattr(self.params, name),
                setter=lambda value, name=name, kind=kind: setattr(
                    self.params, name, str(value) if kind is String else float(value)),
                **parameter), nested=False)
        self.binding = CoreBinding(self, PartCore.interface, PART_OUTPUTS)

    def build_core(self):
        return PartCore(build_part(self.params, self.resources))
