"""Constraint stabilization methods (MATH.md section 3), one per module, chosen by name."""

from __future__ import annotations

from ..errors import PinstabError, choices
from .base import Correction, Stabilizer
from .baumgarte import DEFAULT_KD, DEFAULT_KP, BaumgarteStabilizer, PinocchioNativeStabilizer
from .none import NoStabilizer
from .projection import PostStabilizer, ProjectionStabilizer

METHODS = ("none", "baumgarte", "projection", "post", "pinocchio")


def make_stabilizer(method: str, kp: float | None = None, kd: float | None = None) -> Stabilizer:
    """Build a stabilizer by method name.

    Args:
        method: one of :data:`METHODS`.
        kp: Baumgarte Kp [1/s^2] (``baumgarte``, ``pinocchio``); default 100.
        kd: Baumgarte Kd [1/s]; default 20 (critical damping with the default Kp).
    """
    if method not in METHODS:
        raise PinstabError(f"unknown method {method!r}; valid methods: {choices(METHODS)}")
    if method in ("baumgarte", "pinocchio"):
        cls = BaumgarteStabilizer if method == "baumgarte" else PinocchioNativeStabilizer
        return cls(DEFAULT_KP if kp is None else kp, DEFAULT_KD if kd is None else kd)
    if kp is not None or kd is not None:
        raise PinstabError(f"method {method!r} takes no Kp/Kd gains; they apply to baumgarte and pinocchio")
    return {"none": NoStabilizer, "projection": ProjectionStabilizer, "post": PostStabilizer}[method]()


__all__ = [
    "METHODS",
    "BaumgarteStabilizer",
    "Correction",
    "NoStabilizer",
    "PinocchioNativeStabilizer",
    "PostStabilizer",
    "ProjectionStabilizer",
    "Stabilizer",
    "make_stabilizer",
]
