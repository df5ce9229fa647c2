"""``none``: the bare index reduction, no stabilization (drift grows)."""

from __future__ import annotations

from ..registry import NoOptions
from .base import STABILIZERS, Stabilizer


@STABILIZERS.register("none", options=NoOptions, summary="no stabilization: the constraints drift")
class NoStabilizer(Stabilizer):
    """gamma_stab = 0 and no correction, not even before a singular passage (the drift and its
    consequences are what this method is for)."""

    name = "none"
    guards_passages = False

    def __init__(self, options: NoOptions | None = None) -> None:
        pass

    def baumgarte_gains(self) -> tuple[float, float]:
        return (0.0, 0.0)
