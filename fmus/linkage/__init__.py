"""Planar rigid multibody core (:mod:`.core`), its parts list (:mod:`.elements`),
motion laws (:mod:`.laws`), the shipped mechanisms (:mod:`.scenes`) and the Linkage2D FMU's
model class (:mod:`.slave`, imported by its script :mod:`.linkage_fmu`)."""
from .core import Linkage, LinkageConvergenceError
from .elements import (AngleDriver, Body, Bushing, Mechanism, Port, Prismatic, Revolute,
                       SpringDamper)
from .laws import ConstantSpeed, CosineRampSpeed, SineAngle

__all__ = ["Linkage", "LinkageConvergenceError", "AngleDriver", "Body", "Bushing",
           "Mechanism", "Port", "Prismatic", "Revolute", "SpringDamper", "ConstantSpeed",
           "CosineRampSpeed", "SineAngle"]
