"""Flexible planar link: beam matrices (:mod:`.beam`) and the floating-frame PIM core
(:mod:`.core`)."""
from .core import FlexibleLink, PIMConvergenceError

__all__ = ["FlexibleLink", "PIMConvergenceError"]
