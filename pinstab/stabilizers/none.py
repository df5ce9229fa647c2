"""``none``: the bare index reduction, no stabilization (drift grows)."""

from __future__ import annotations

from ..registry import NoOptions
from .base import STABILIZERS, Stabilizer


@STABILIZERS.register("none", options=NoOptions, summary="no stabilization: the constraints drift")
class NoStabilizer(Stabilizer):
    """gamma_stab = 0 and no correction."""

    name = "none"

    def __init__(self, options: NoOptions | None = None) -> None:
        pass

    def baumgarte_gains(self) -> tuple[float, float]:
        return (0.0, 0.0)
