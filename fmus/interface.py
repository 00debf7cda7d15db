"""The contract every glueable physics core follows, with no FMI in sight.

A *core* is a subsystem model (spring-mass chain, elastic body, linkage) that the
gluing master can drive through its interface: the forces at its port degrees of
freedom go in, the motion of those degrees of freedom comes out.  The pythonfmu
wrappers in ``fmus/*/fmu.py`` map FMI variables onto this contract and nothing more,
and the master's in-process adapter drives a core directly in algorithm tests.

Conventions (see DESIGN.md, "Ports"):

* ``interface`` lists the glueable degrees of freedom as ``(port, dof)`` pairs, dof
  one of ``x y z rx ry rz``; every vector below follows that order.
* Forces are applied *to* the subsystem at the port, in N (N.m for r*), global frame.
* A step from ``t`` to ``t + h`` holds the interface forces constant over the step
  and satisfies equilibrium at ``t + h`` with them (implicit rules: trapezoidal,
  Newmark average acceleration), which is what T-T gluing solves for.
* Kinematics are global positions (m, rad), velocities and accelerations.
"""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

DOF_NAMES = ("x", "y", "z", "rx", "ry", "rz")


class InterfaceCore(ABC):
    """Base class of a glueable physics core (see module docstring)."""

    #: ``(port, dof)`` pairs, the order of force and kinematics vectors.
    interface: tuple[tuple[str, str], ...] = ()
    #: Current simulation time in s.
    time: float = 0.0

    @abstractmethod
    def initialize(self, start_time: float) -> None:
        """Set time to ``start_time`` and make accelerations consistent with the
        initial state, the loads at ``start_time`` and the current interface forces."""

    @abstractmethod
    def set_interface_forces(self, forces: np.ndarray) -> None:
        """Set the interface forces (N, N.m), one entry per ``interface`` pair."""

    @abstractmethod
    def step(self, time: float, step_size: float) -> None:
        """Advance from ``time`` to ``time + step_size`` (s) with the forces held."""

    @abstractmethod
    def interface_kinematics(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (m, rad), velocities and accelerations at the interface."""

    def interface_kinematic(self, kind: int) -> np.ndarray:
        """One part of :meth:`interface_kinematics`: 0 positions, 1 velocities,
        2 accelerations (a core that can compute one alone overrides this)."""
        return self.interface_kinematics()[kind]

    def kinematic_reader(self, kind: int, rows: np.ndarray):
        """A function of no arguments that returns entries ``rows`` of
        :meth:`interface_kinematic` (``kind``) as they are when it is called, the same
        numbers; None when the core has no cheaper way than computing them all (the
        default).  The FMU binding answers a batched read of one kind with it."""
        return None

    @abstractmethod
    def get_state(self) -> dict:
        """A deep copy of the complete numerical state (restoring it and
        repeating a step must reproduce that step bit for bit)."""

    @abstractmethod
    def set_state(self, state: dict) -> None:
        """Restore a state returned by :meth:`get_state`."""

    def caches(self):
        """What the core keeps from its past besides its state (caches that decide
        how, not what, it computes), as references; None when it keeps nothing.  A
        state moved to a fresh instance in another process carries it, so that the
        fresh instance computes what this one would, bit for bit; a rollback in the
        same instance does not restore it."""
        return None

    def set_caches(self, caches) -> None:
        """Take over the :meth:`caches` of another instance of the same core."""

    def outputs(self) -> dict[str, float]:
        """Named scalar outputs beyond the ports (for example ``x[1]``)."""
        return {}
