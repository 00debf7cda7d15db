"""FMI 2.0 co-simulation wrapper of one part of a planar linkage
(:class:`fmus.linkage.parts.PartCore` over :class:`fmus.linkage.core.Linkage`).

String parameters ``scene`` (``crank_slider`` or ``four_bar``) and ``part``
(crank, coupler, slider / crank, coupler, rocker) select the part; the crank
slider's sizes (seed section 4.2.1), gravity and the constraint stabilisation
(``formulation``, ``baumgarte_frequency`` w rad/s, ``baumgarte_damping`` xi) are
parameters too, so one FMU serves every linkage scene.  Ports A, B, P (dofs x y)
follow DESIGN.md; a port the part lacks takes no force and reports zero motion.
Outputs: the part's body ``x y theta vx vy omega ax ay alpha``, the driver
``torque``, ``constraint_violation`` and ``newton_iterations``.
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
    "scene": "crank_slider or four_bar",
    "part": "crank, coupler, slider (crank_slider) or crank, coupler, rocker (four_bar)",
    "crank_mass": "crank mass, kg", "crank_length": "crank length, m",
    "coupler_length": "coupler length, m", "coupler_section": "coupler square section side, m",
    "coupler_density": "coupler density, kg/m^3", "slider_mass": "slider mass, kg",
    "speed": "crank speed after the ramp, rad/s", "ramp_time": "crank speed ramp time, s",
    "gravity_x": "gravity x, m/s^2", "gravity_y": "gravity y, m/s^2",
    "formulation": "constraint rows: baumgarte or index3",
    "baumgarte_frequency": "Baumgarte w, rad/s", "baumgarte_damping": "Baumgarte xi",
}


@glued_slave
class Linkage2D(Fmi2Slave):
    """One rigid part of the crank slider or the four bar, glueable at A, B, P."""

    author = "dsim"
    description = "Planar rigid multibody part (trapezoidal rule, Baumgarte rows)"

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
        return PartCore(build_part(self.params))
