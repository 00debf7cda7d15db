"""What every pythonfmu wrapper of an :class:`~fmus.interface.InterfaceCore` shares.

pythonfmu finds the model class by a regular expression that wants
``class Name(Fmi2Slave):`` verbatim, so the shared part cannot be a base class;
it is this binding object, which a wrapper creates in ``__init__`` and calls from
its FMI callbacks.  It registers the port variables of DESIGN.md (``P.f_x`` input,
``P.u_x``/``P.v_x``/``P.a_x`` outputs), caches the outputs after every step, and
implements the complete FMU state (the core's numerical state plus inputs).

In initialization mode the port outputs follow the force inputs (FMI 2.0 lets a
master read calculated outputs there): the core is built at the first read, and
every force written recomputes the initial accelerations.  A master can so find
start forces that make the initial accelerations compatible before the first step.
"""
from __future__ import annotations

import abc
import pickle

import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Variability, Real

from fmus.interface import InterfaceCore

KINEMATIC_PREFIXES = ("u", "v", "a")


class CoreBinding:
    """Port variables, output cache and state of one wrapped core."""

    def __init__(self, slave, interface, output_names=()):
        self.slave = slave
        self.interface = tuple(interface)
        self.core: InterfaceCore | None = None
        self.initializing = False
        self.start_time = 0.0
        self.forces = np.zeros(len(self.interface))
        self.kinematics = np.zeros((3, len(self.interface)))
        self.output_values = {name: 0.0 for name in output_names}
        for i, (port, dof) in enumerate(self.interface):
            slave.register_variable(Real(
                f"{port}.f_{dof}", causality=Fmi2Causality.input,
                variability=Fmi2Variability.continuous, start=0.0,
                description="force (moment for r*) applied at the port, N or N.m",
                getter=lambda i=i: float(self.forces[i]),
                setter=lambda value, i=i: self._set_force(i, value)), nested=False)
        for row, (prefix, what) in enumerate(zip(
                KINEMATIC_PREFIXES, ("position", "velocity", "acceleration"))):
            for i, (port, dof) in enumerate(self.interface):
                slave.register_variable(Real(
                    f"{port}.{prefix}_{dof}", causality=Fmi2Causality.output,
                    variability=Fmi2Variability.continuous,
                    description=f"global {what} of the port",
                    getter=lambda row=row, i=i: self._kinematic(row, i)),
                    nested=False)
        for name in output_names:
            slave.register_variable(Real(
                name, causality=Fmi2Causality.output,
                variability=Fmi2Variability.continuous,
                getter=lambda name=name: self.output_values[name]), nested=False)

    def _set_force(self, index: int, value: float) -> None:
        self.forces[index] = value
        if self.core is not None:
            self.core.set_interface_forces(self.forces)
            if self.initializing:  # the start forces decide the initial accelerations
                self.core.initialize(self.start_time)
                self.refresh()

    def _kinematic(self, row: int, index: int) -> float:
        if self.core is None and self.initializing:
            self.attach(self.slave.build_core(), self.start_time)
        return float(self.kinematics[row, index])

    def attach(self, core: InterfaceCore, start_time: float) -> None:
        """Take over a freshly built core and initialise it at ``start_time``."""
        self.core = core
        core.set_interface_forces(self.forces)
        core.initialize(start_time)
        self.refresh()

    def refresh(self) -> None:
        """Copy the core's kinematics and named outputs into the output cache."""
        u, v, a = self.core.interface_kinematics()
        self.kinematics[0], self.kinematics[1], self.kinematics[2] = u, v, a
        self.output_values.update(self.core.outputs())

    def step(self, time: float, step_size: float) -> bool:
        self.core.step(time, step_size)
        self.refresh()
        return True

    def get_state(self) -> dict:
        """The complete FMU state: core state, inputs (a restore must bring back
        the inputs too, as fmi2SetFMUstate does) and nothing derived."""
        return {"core": self.core.get_state() if self.core else None,
                "forces": self.forces.copy()}

    def set_state(self, state: dict) -> None:
        self.forces = np.array(state["forces"], dtype=float)
        if self.core is not None and state["core"] is not None:
            self.core.set_state(state["core"])
            self.core.set_interface_forces(self.forces)
            self.refresh()


def state_to_bytes(state) -> bytes:
    """Serialise an FMU state (numpy arrays inside, so pickle rather than JSON)."""
    return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)


def state_from_bytes(data: bytes):
    """Inverse of :func:`state_to_bytes`."""
    return pickle.loads(data)


def glued_slave(cls):
    """Class decorator for a pythonfmu slave of a glueable core.

    The slave's ``__init__`` creates ``self.binding`` (a :class:`CoreBinding`) and the
    slave defines ``build_core(self)``, which makes the core from the parameters set
    so far; this decorator adds the FMI callbacks every such wrapper shares (start
    time, initialisation, step, complete state and its serialisation).  A
    ``ValueError`` from ``build_core`` is logged as an fmi2Error, so a master can tell
    the user which parameter the model refused.  (A decorator and not a base class:
    pythonfmu finds the model class by the literal line ``class Name(Fmi2Slave):``.)
    """
    from pythonfmu.enums import Fmi2Status

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self.binding.start_time = start_time

    def enter_initialization_mode(self):
        self.binding.initializing = True

    def build_core_logged(self):
        try:
            return build_core(self)
        except ValueError as error:
            self.log(f"{self.instance_name}: {error}", Fmi2Status.error)
            raise

    def exit_initialization_mode(self):
        binding = self.binding
        if binding.core is None:
            binding.attach(self.build_core(), binding.start_time)
        binding.initializing = False

    def do_step(self, current_time, step_size):
        return self.binding.step(current_time, step_size)

    def _get_fmu_state(self):
        return self.binding.get_state()

    def _set_fmu_state(self, state):
        self.binding.set_state(state)

    build_core = cls.build_core
    for method in (setup_experiment, enter_initialization_mode, exit_initialization_mode,
                   do_step, _get_fmu_state, _set_fmu_state):
        if method.__name__ not in cls.__dict__:
            setattr(cls, method.__name__, method)
    cls.build_core = build_core_logged
    cls._fmu_state_to_bytes = staticmethod(state_to_bytes)
    cls._fmu_state_from_bytes = staticmethod(state_from_bytes)
    abc.update_abstractmethods(cls)
    return cls
