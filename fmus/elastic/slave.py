"""The ElasticBody FMU's model class: FMI 2.0 co-simulation slave of an elastic
finite-element body read from a mesh file (pythonfmu), which the FMU's script
:mod:`fmus.elastic.elastic_body_fmu` imports.

One FMU for every FE body, 2-D (plane stress) or 3-D (solid): what it models comes from
parameters and the mesh file (see :mod:`fmus.elastic.body_spec` and docs/elastic_body.md):
``mesh_file``, ``order``, material, ``thickness``, ``mass``, Rayleigh damping,
``fidelity`` (full, craig_bampton with ``modes``, rigid), ``clamped``, node-set ports
``port1`` .. ``port4`` (slots ``portK[1]`` .. ``portK[41]``, dofs x y z, ``portK.nodes``
glued), rigid ports ``rigid1`` .. ``rigid4`` (dofs x y z rx ry rz), a sine point load and
probes (outputs ``load.u_*``, ``probeK.u_*``).

A body the parameters cannot make (a mesh file that is no mesh, an empty or miscounted
node set, an unknown fidelity) is refused with the reason logged at fmi2Error, never with
fmi2Fatal, so that the master can free the instance (:mod:`fmus.fmi_binding`).  The
variables are declared once for the class (:class:`fmus.fmi_binding.Variable`), not
registered by each instance.
"""
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real, String

from ..fmi_binding import CoreBinding, Variable, glued_slave, port_variables
from .body_spec import PARAMETERS, BodySpec, SlotBody, build_body, get_parameter, set_parameter

TYPES = {"Real": Real, "Integer": Integer, "String": String}


def _parameters() -> list[Variable]:
    """The parameters, in the order of :data:`fmus.elastic.body_spec.PARAMETERS` (their
    value references), each read from and written to the instance's ``spec``."""
    return [Variable(
        TYPES[kind], name, description=text, causality=Fmi2Causality.parameter,
        variability=Fmi2Variability.fixed,
        get=lambda slave, name=name: get_parameter(slave.spec, name),
        set=lambda slave, value, name=name: set_parameter(slave.spec, name, value))
        for name, (kind, text, _) in PARAMETERS.items()]


@glued_slave
class ElasticBody(Fmi2Slave):
    """Linear elastic FE body from a mesh file (Newmark average acceleration), glued at
    node-set and rigid ports."""

    author = "dsim"
    description = "Linear elastic FE body (2-D or 3-D) from a mesh file and parameters"
    variables = (*_parameters(), *port_variables(SlotBody.interface, SlotBody.output_names))

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.spec = BodySpec()
        self.binding = CoreBinding(self, SlotBody.interface, SlotBody.output_names)

    def build_core(self):
        return SlotBody(build_body(self.spec, self.resources))
