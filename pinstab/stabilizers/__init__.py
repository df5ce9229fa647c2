"""Constraint stabilization methods (MATH.md section 3), one per module, chosen by name."""

from __future__ import annotations

from ..errors import PinstabError, choices
from .base import Correction, Stabilizer
from .baumgarte import DEFAULT_KD, DEFAULT_KP, BaumgarteStabilizer, PinocchioNativeStabilizer
from .mukharlyamov import DEFAULT_DECAY, VARIANTS, MukharlyamovStabilizer
from .none import NoStabilizer
from .projection import PostStabilizer, ProjectionStabilizer

METHODS = ("none", "baumgarte", "mukharlyamov", "projection", "post", "pinocchio")


def make_stabilizer(
    method: str,
    kp: float | None = None,
    kd: float | None = None,
    variant: str | None = None,
    decay: float | None = None,
    hold: bool | None = None,
) -> Stabilizer:
    """Build a stabilizer by method name.

    Args:
        method: one of :data:`METHODS`.
        kp: Baumgarte Kp [1/s^2] (``baumgarte``, ``pinocchio``; default 100), or the stiffness H of
            ``mukharlyamov`` given gains [1/s^2 kinematic, N/m inertial].
        kd: Baumgarte Kd [1/s] (default 20), or the damping B of ``mukharlyamov`` [1/s, N s/m].
        variant: ``mukharlyamov`` only: ``kinematic`` (default) or ``inertial``.
        decay: ``mukharlyamov`` automatic gains only: decay factor r per step (default 0 kinematic, 0.3 inertial).
        hold: ``mukharlyamov`` with heun or rk4: hold the term over the step (default True).
    """
    if method not in METHODS:
        raise PinstabError(f"unknown method {method!r}; valid methods: {choices(METHODS)}")
    if method != "mukharlyamov" and (variant is not None or decay is not None or hold is not None):
        raise PinstabError(f"variant, decay and hold apply to method mukharlyamov, not {method!r}")
    if method == "mukharlyamov":
        if decay is not None and kp is not None:
            raise PinstabError(
                "mukharlyamov: the decay factor sets automatic gains; it cannot be combined with --kp/--kd"
            )
        return MukharlyamovStabilizer(variant or "kinematic", kp, kd, decay, True if hold is None else hold)
    if method in ("baumgarte", "pinocchio"):
        cls = BaumgarteStabilizer if method == "baumgarte" else PinocchioNativeStabilizer
        return cls(DEFAULT_KP if kp is None else kp, DEFAULT_KD if kd is None else kd)
    if kp is not None or kd is not None:
        raise PinstabError(
            f"method {method!r} takes no Kp/Kd gains; they apply to baumgarte, pinocchio and mukharlyamov"
        )
    return {"none": NoStabilizer, "projection": ProjectionStabilizer, "post": PostStabilizer}[method]()


__all__ = [
    "DEFAULT_DECAY",
    "METHODS",
    "VARIANTS",
    "BaumgarteStabilizer",
    "MukharlyamovStabilizer",
    "Correction",
    "NoStabilizer",
    "PinocchioNativeStabilizer",
    "PostStabilizer",
    "ProjectionStabilizer",
    "Stabilizer",
    "make_stabilizer",
]
