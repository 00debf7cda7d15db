"""FMI 2.0 co-simulation wrapper of an elastic finite-element body read from a mesh file.

One FMU for every FE body, 2-D (plane stress) or 3-D (solid): what it models comes from
parameters and the mesh file (see :mod:`fmus.elastic.body_spec` and docs/elastic_body.md):
``mesh_file``, ``order``, material, ``thickness``, ``mass``, Rayleigh damping,
``fidelity`` (full, craig_bampton with ``modes``, rigid), ``clamped``, node-set ports
``port1`` .. ``port4`` (slots ``portK[1]`` .. ``portK[41]``, dofs x y z, ``portK.nodes``
glued), rigid ports ``rigid1`` .. ``rigid4`` (dofs x y z rx ry rz), a sine point load and
probes (outputs ``load.u_*``, ``probeK.u_*``).

A body the parameters cannot make (a mesh file that is no mesh, an empty or miscounted
node set, an unknown fidelity) is refused with the reason logged at fmi2Error, never with
fmi2Fatal, so that the master can free the instance (:mod:`fmus.fmi_binding`).
"""
import os
import sys

# Another dsim FMU in this process may have imported the fmus package from its own
# resources folder, which its master may since have deleted: look in ours first.
_OWN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fmus")
if "fmus" in sys.modules and os.path.isdir(_OWN) and _OWN not in sys.modules["fmus"].__path__:
    sys.modules["fmus"].__path__.insert(0, _OWN)

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String

from fmus.elastic.body_spec import (PARAMETERS, BodySpec, SlotBody, build_body,
                                    get_parameter, set_parameter)
from fmus.fmi_binding import CoreBinding, glued_slave

TYPES = {"Real": Real, "Integer": Integer, "String": String}


@glued_slave
class ElasticBody(Fmi2Slave):
    """Linear elastic FE body from a mesh file (Newmark average acceleration), glued at
    node-set and rigid ports."""

    author = "dsim"
    description = "Linear elastic FE body (2-D or 3-D) from a mesh file and parameters"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.spec = BodySpec()
        for name, (kind, text, _) in PARAMETERS.items():
            self.register_variable(TYPES[kind](
                name, description=text, causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.fixed,
                getter=lambda name=name: get_parameter(self.spec, name),
                setter=lambda value, name=name: set_parameter(self.spec, name, value)),
                nested=False)
        self.binding = CoreBinding(self, SlotBody.interface, SlotBody.output_names)

    def build_core(self):
        return SlotBody(build_body(self.spec, self.resources))
