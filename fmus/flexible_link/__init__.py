"""Flexible planar link: beam matrices (:mod:`.beam`) and the floating-frame PIM core
(:mod:`.core`), and the FlexibleLink2D FMU's model class (:mod:`.slave`, imported by its script
:mod:`.flexible_link_fmu`)."""
from .core import FlexibleLink, PIMConvergenceError

__all__ = ["FlexibleLink", "PIMConvergenceError"]
