"""Constraint families: loop closures between frames, user-defined holonomic and Pfaffian rows."""

from .base import Constraint
from .custom import HolonomicConstraint, PfaffianConstraint
from .loops import CLOSURE_KINDS, FrameClosure
from .stack import ConstraintSet, ConstraintValues

__all__ = [
    "CLOSURE_KINDS",
    "Constraint",
    "ConstraintSet",
    "ConstraintValues",
    "FrameClosure",
    "HolonomicConstraint",
    "PfaffianConstraint",
]
