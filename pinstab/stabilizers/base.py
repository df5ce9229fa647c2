"""What a stabilizer provides (MATH.md section 3): a term gamma_stab and/or a post-step correction."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..constraints import ConstraintValues

if TYPE_CHECKING:
    from ..system import ConstrainedSystem


@dataclass
class Correction:
    """A post-step correction: the corrected state and the iterations it took."""

    q: np.ndarray
    v: np.ndarray
    iterations: int = 0


class Stabilizer:
    """Base stabilizer: no term, no correction.

    Attributes:
        name: method name (``none``, ``baumgarte``, ``projection``, ``post``, ``pinocchio``, ...).
        required_solver: a KKT backend the method implies (``pinocchio``), else None.
    """

    name = "none"
    required_solver: str | None = None

    def stabilization_term(self, values: ConstraintValues, holonomic_mask: np.ndarray) -> np.ndarray | None:
        """gamma_stab (s,) added to the acceleration-level right-hand side, or None for zero."""
        return None

    def baumgarte_gains(self) -> tuple[float, float] | None:
        """(Kp, Kd) when the term is Baumgarte's (so Pinocchio's corrector can apply it), else None."""
        return (0.0, 0.0)

    def correct(self, system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, t: float) -> Correction:
        """Correct the state after a step; the default leaves it as it is."""
        return Correction(q, v)

    def parameters(self) -> dict[str, float]:
        """The method's parameters, for reports."""
        return {}
