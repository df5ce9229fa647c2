"""Constraint families: loop closures between frames, plane contacts, user-defined holonomic and
Pfaffian rows. Every module here registers its scene-file kinds in :data:`CONSTRAINT_KINDS`."""

from ..contact.cones import FrictionCone
from ..registry import load_extensions
from .base import CONSTRAINT_KINDS, Constraint, RowKind, VelocityTerms
from .contacts import PointContact
from .custom import HolonomicConstraint, PfaffianConstraint
from .grasp_contacts import FingertipContact
from .loops import FrameClosure
from .stack import ConeRows, ConstraintSet, ConstraintValues, RowLayout, Violation

load_extensions(__name__, __path__)

__all__ = [
    "CONSTRAINT_KINDS",
    "ConeRows",
    "Constraint",
    "ConstraintSet",
    "ConstraintValues",
    "FingertipContact",
    "FrameClosure",
    "FrictionCone",
    "HolonomicConstraint",
    "PfaffianConstraint",
    "PointContact",
    "RowKind",
    "RowLayout",
    "VelocityTerms",
    "Violation",
]
