"""``none``: the bare index reduction, no stabilization (drift grows)."""

from __future__ import annotations

from .base import Stabilizer


class NoStabilizer(Stabilizer):
    """gamma_stab = 0 and no correction."""

    name = "none"
