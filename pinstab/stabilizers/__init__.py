"""Constraint stabilization methods (docs/mathematics.md section 3), one per module, each registered in
:data:`STABILIZERS` (``none``, ``baumgarte``, ``mukharlyamov``, ``projection``, ``post``, ``pinocchio``)."""

from ..registry import load_extensions
from .base import STABILIZERS, CoreTerm, Correction, DeviationGains, Stabilizer
from .baumgarte import DEFAULT_KD, DEFAULT_KP, BaumgarteOptions, BaumgarteStabilizer, PinocchioNativeStabilizer
from .mukharlyamov import DEFAULT_DECAY, VARIANTS, MukharlyamovOptions, MukharlyamovStabilizer
from .none import NoStabilizer
from .projection import PostStabilizer, ProjectionOptions, ProjectionStabilizer

load_extensions(__name__, __path__)

__all__ = [
    "DEFAULT_DECAY",
    "DEFAULT_KD",
    "DEFAULT_KP",
    "STABILIZERS",
    "VARIANTS",
    "BaumgarteOptions",
    "BaumgarteStabilizer",
    "CoreTerm",
    "Correction",
    "DeviationGains",
    "MukharlyamovOptions",
    "MukharlyamovStabilizer",
    "NoStabilizer",
    "PinocchioNativeStabilizer",
    "PostStabilizer",
    "ProjectionOptions",
    "ProjectionStabilizer",
    "Stabilizer",
]
