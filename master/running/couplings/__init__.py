"""Couplings: how the subsystems advance together over a macro step (a registry;
``coupling=`` names one).  All share the template step of :class:`Coupling`."""
from dsim.master.running.couplings.base import CausalCoupling, Coupling, StepReport
from dsim.master.running.couplings.explicit import ExplicitCoupling
from dsim.master.running.couplings.iterative import IterativeCoupling
from dsim.master.running.couplings.strong import StrongCoupling

COUPLINGS = {c.name: c for c in (IterativeCoupling, ExplicitCoupling, CausalCoupling,
                                 StrongCoupling)}

__all__ = ["COUPLINGS", "CausalCoupling", "Coupling", "ExplicitCoupling",
           "IterativeCoupling", "StepReport", "StrongCoupling"]
