"""``baumgarte`` (1972) and ``pinocchio`` (the same corrector applied inside Pinocchio)."""

from __future__ import annotations

import math

import numpy as np

from ..constraints import ConstraintValues
from ..errors import PinstabError
from .base import Stabilizer

DEFAULT_KP = 100.0  # [1/s^2]: beta = 10 1/s
DEFAULT_KD = 20.0  # [1/s]: alpha = 10 1/s, critically damped with DEFAULT_KP


class BaumgarteStabilizer(Stabilizer):
    """``gamma_stab = -Kd g - Kp phi`` on holonomic rows, ``-(Kd/2) g`` on nonholonomic rows.

    Args:
        kp: Kp = beta^2 [1/s^2].
        kd: Kd = 2 alpha [1/s].
    """

    name = "baumgarte"

    def __init__(self, kp: float = DEFAULT_KP, kd: float = DEFAULT_KD) -> None:
        for label, value in (("kp", kp), ("kd", kd)):
            if not math.isfinite(value) or value < 0:
                raise PinstabError(f"baumgarte: gain {label} must be a finite number >= 0, got {value}")
        self.kp, self.kd = float(kp), float(kd)

    def deviation_gains(self, system, q, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        mask = system.constraints.holonomic_mask
        return self.kp * np.eye(len(mask))[:, mask], np.diag(np.where(mask, self.kd, 0.5 * self.kd)), mask

    def stabilization_term(self, system, q, v, t, values: ConstraintValues, stage: int) -> np.ndarray:
        velocity_gain = np.where(system.constraints.holonomic_mask, self.kd, 0.5 * self.kd)
        return -velocity_gain * values.velocity_residual - self.kp * values.phi

    def baumgarte_gains(self) -> tuple[float, float]:
        return (self.kp, self.kd)

    def parameters(self) -> dict[str, float]:
        return {"kp": self.kp, "kd": self.kd}


class PinocchioNativeStabilizer(BaumgarteStabilizer):
    """Pinocchio's ``constraintDynamics`` with its own Baumgarte corrector (the fast path peer)."""

    name = "pinocchio"
    required_solver = "pinocchio"
