"""``baumgarte`` (1972) and ``pinocchio`` (the same corrector applied inside Pinocchio)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import kernels
from ..constraints import ConstraintValues
from .base import STABILIZERS, DeviationGains, Stabilizer

DEFAULT_KP = 100.0  # [1/s^2]: beta = 10 1/s
DEFAULT_KD = 20.0  # [1/s]: alpha = 10 1/s, critically damped with DEFAULT_KP


@dataclass(frozen=True)
class BaumgarteOptions:
    """Baumgarte gains."""

    kp: float = field(default=DEFAULT_KP, metadata={"help": "Kp = beta^2 [1/s^2] (default 100)"})
    kd: float = field(default=DEFAULT_KD, metadata={"help": "Kd = 2 alpha [1/s] (default 20)"})

    def __post_init__(self) -> None:
        for label in ("kp", "kd"):
            value = getattr(self, label)
            if isinstance(value, bool) or not isinstance(value, float | int) or not math.isfinite(value) or value < 0:
                raise ValueError(f"gain {label} must be a finite number >= 0, got {value!r}")


@STABILIZERS.register("baumgarte", options=BaumgarteOptions, summary="Baumgarte's term -Kd g - Kp phi")
class BaumgarteStabilizer(Stabilizer):
    """``gamma_stab = -Kd g - Kp phi`` on holonomic rows, ``-(Kd/2) g`` on nonholonomic rows.

    Args:
        options: Kp = beta^2 [1/s^2], Kd = 2 alpha [1/s].
    """

    name = "baumgarte"

    def __init__(self, options: BaumgarteOptions | None = None) -> None:
        options = options or BaumgarteOptions()
        self.kp, self.kd = float(options.kp), float(options.kd)

    def deviation_gains(self, model, q, v) -> DeviationGains:
        mask = model.constraints.holonomic_mask
        return DeviationGains(
            self.kp * np.eye(len(mask))[:, mask], np.diag(kernels.baumgarte_velocity_gains(self.kd, mask)), mask
        )

    def stabilization_term(self, model, q, v, t, values: ConstraintValues, stage: int) -> np.ndarray:
        gains = kernels.baumgarte_velocity_gains(self.kd, model.constraints.holonomic_mask)
        return kernels.stabilization_term(self.kp, gains, values.phi, values.velocity_residual)  # the core's

    def baumgarte_gains(self) -> tuple[float, float]:
        return (self.kp, self.kd)

    def parameters(self) -> dict[str, float | str]:
        return {"kp": self.kp, "kd": self.kd}


@STABILIZERS.register(
    "pinocchio", options=BaumgarteOptions, summary="Pinocchio's constraintDynamics with its own Baumgarte corrector"
)
class PinocchioNativeStabilizer(BaumgarteStabilizer):
    """Pinocchio's ``constraintDynamics`` with its own Baumgarte corrector (the fast path peer)."""

    name = "pinocchio"
    required_solver = "pinocchio"
