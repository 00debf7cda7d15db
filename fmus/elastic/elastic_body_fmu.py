"""FMI 2.0 co-simulation wrapper of a 2-D :class:`fmus.elastic.core.ElasticBody`.

One FMU serves every part of the ladder frame and any user mesh: the body is chosen by
parameters (``part``, ``element_size``, ``mass``, ``modes``, ``mesh_file`` ...; see
:class:`fmus.elastic.parts.PartSpec`). The variable list is fixed: ports ``left``,
``right``, ``front``, ``mid``, ``rear``, ``center``, each with node slots ``S[1]`` ..
``S[41]`` (inputs ``S[k].f_x``, ``S[k].f_y``; outputs ``S[k].u_x`` ... ``S[k].a_y``), and
the Integer parameter ``S.nodes``: how many of the slots the scene glues, checked against
the body's node set when the FMU initialises. Output ``load.u_x``, ``load.u_y``: the probe
(the frame's load point on cross_front; zero on parts without one).

A body the parameters cannot make (unknown part, a mesh file that is no mesh, an empty or
miscounted node set) fails fmi2ExitInitializationMode with the reason logged as an error.
"""
import os
import sys

# Another dsim FMU in this process may have imported the fmus package from its own
# resources folder, which its master may since have deleted: look in ours first.
_OWN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fmus")
if "fmus" in sys.modules and os.path.isdir(_OWN) and _OWN not in sys.modules["fmus"].__path__:
    sys.modules["fmus"].__path__.insert(0, _OWN)

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String

from fmus.elastic.parts import DOFS, MAX_NODES, PORTS, PartSpec, SlotBody, build_body
from fmus.fmi_binding import CoreBinding, glued_slave

REALS = {
    "element_size": "element size of the frame parts' structured mesh, m",
    "thickness": "plate thickness (plane stress), m",
    "youngs_modulus": "Young's modulus, Pa",
    "poisson_ratio": "Poisson ratio, -",
    "density": "density, kg/m^3",
    "load_frequency": "part 'mesh': frequency of the sine point load, Hz",
}
STRINGS = {
    "part": "rail_left, rail_right, cross_front, cross_mid, cross_rear, or mesh (mesh_file)",
    "mass": "consistent or lumped",
    "mesh_file": "part 'mesh': mesh file, relative to the FMU's resources folder",
    "clamped": "part 'mesh': clamped node set ('box x0 y0 x1 y1', 'point x y' or a boundary)",
}


@glued_slave
class ElasticBody2D(Fmi2Slave):
    """Plane-stress finite-element body (Newmark average acceleration), glued at node sets."""

    author = "dsim"
    description = "2-D linear elastic FE body (frame parts or a user mesh), node-set ports"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.spec = PartSpec()
        parameter = dict(causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed)

        def attribute(name, kind):
            return dict(getter=lambda: getattr(self.spec, name),
                        setter=lambda value: setattr(self.spec, name, kind(value)))

        for name, text in STRINGS.items():
            self.register_variable(String(name, description=text, **attribute(name, str),
                                          **parameter), nested=False)
        for name, text in REALS.items():
            self.register_variable(Real(name, description=text, **attribute(name, float),
                                        **parameter), nested=False)
        self.register_variable(Integer(
            "modes", description="0: full mesh; N: Craig-Bampton with N fixed-interface modes",
            **attribute("modes", int), **parameter), nested=False)
        for i, dof in enumerate(DOFS):
            self.register_variable(Real(
                f"load.point_{dof}", description="part 'mesh': load and probe point, m",
                getter=lambda i=i: self.spec.load_point[i],
                setter=lambda value, i=i: self._set_pair("load_point", i, value),
                **parameter), nested=False)
            self.register_variable(Real(
                f"load.F_{dof}", description="part 'mesh': sine load amplitude, N",
                getter=lambda i=i: self.spec.load_amplitude[i],
                setter=lambda value, i=i: self._set_pair("load_amplitude", i, value),
                **parameter), nested=False)
        self.register_variable(Integer(
            "load.probe", description="part 'mesh': 1 adds the probe 'load' at load.point",
            getter=lambda: int(self.spec.probe),
            setter=lambda value: setattr(self.spec, "probe", bool(value)), **parameter),
            nested=False)
        for port in PORTS:
            self.register_variable(Integer(
                f"{port}.nodes", description=f"nodes of port {port} the scene glues "
                f"(0: unused; at most {MAX_NODES}); must equal its node set's size",
                getter=lambda port=port: self.spec.nodes[port],
                setter=lambda value, port=port: self.spec.nodes.__setitem__(port, int(value)),
                **parameter), nested=False)
            self.register_variable(String(
                f"{port}.set", description=f"part 'mesh': node set of port {port}",
                getter=lambda port=port: self.spec.sets[port],
                setter=lambda value, port=port: self.spec.sets.__setitem__(port, str(value)),
                **parameter), nested=False)
        self.binding = CoreBinding(self, SlotBody.interface, SlotBody.output_names)

    def _set_pair(self, name, index, value):
        pair = list(getattr(self.spec, name))
        pair[index] = float(value)
        setattr(self.spec, name, tuple(pair))

    def build_core(self):
        return SlotBody(build_body(self.spec, self.resources))
