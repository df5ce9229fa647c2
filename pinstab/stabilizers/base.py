"""What a stabilizer provides (MATH.md section 3): a term gamma_stab and/or a post-step correction,
and, where it has one, the discrete stability indicator rho(R(tau W)) of its deviation dynamics."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..constraints import ConstraintValues
from ..stability import amplification, spectral_radius

if TYPE_CHECKING:
    from ..system import ConstrainedSystem


@dataclass
class Correction:
    """A post-step correction: the corrected state and the iterations it took."""

    q: np.ndarray
    v: np.ndarray
    iterations: int = 0


class Stabilizer:
    """Base stabilizer: no term, no correction, no stability indicator.

    Attributes:
        name: method name (``none``, ``baumgarte``, ``projection``, ``post``, ``pinocchio``, ...).
        required_solver: a KKT backend the method implies (``pinocchio``), else None.
    """

    name = "none"
    required_solver: str | None = None
    constant_gains = True  # S and K do not depend on the state: rho is computed once per run

    def bind(self, system: ConstrainedSystem, step: float, integrator: str, q: np.ndarray) -> None:
        """Called once before a run with the step [s], the integrator name and the start configuration."""
        self.step, self.integrator = step, integrator
        self.scheme = integrator  # the amplification matrix R that describes the method's deviations
        self.mask = system.constraints.holonomic_mask
        self._cached_radius: float | None = None

    def deviation_gains(
        self, system: ConstrainedSystem, q: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(S, K, holonomic mask) of the linearized deviations dv~/dt = -S q~ - K v~ at (q, v), or None.

        S is s x m [1/s^2] (columns: holonomic rows), K is s x s [1/s]; s and the mask may be those
        of the deviations that can occur (redundant rows removed) rather than of every row.
        """
        return None

    def stabilization_term(
        self, system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, t: float, values: ConstraintValues, stage: int
    ) -> np.ndarray | None:
        """gamma_stab (s,) added to the acceleration-level right-hand side, or None for zero.

        ``system.kin`` holds the full kinematics at (q, v) when this is called; ``stage`` is the
        integrator's stage index within the step (0 first).
        """
        return None

    def baumgarte_gains(self) -> tuple[float, float] | None:
        """(Kp, Kd) when the term is Baumgarte's (so Pinocchio's corrector can apply it), else None."""
        return (0.0, 0.0)

    def correct(self, system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, t: float) -> Correction:
        """Correct the state after a step; the default leaves it as it is."""
        return Correction(q, v)

    def spectral_radius(self, system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, t: float) -> float | None:
        """rho(R(tau W)) of the deviation dynamics at (q, v, t) [dimensionless], or None for a method
        without a stabilization term; needs :meth:`bind` first."""
        if self.constant_gains and self._cached_radius is not None:
            return self._cached_radius
        gains = self.deviation_gains(system, q, v)
        if gains is None:
            return None
        radius = spectral_radius(amplification(*gains, self.step, self.scheme))
        if self.constant_gains:
            self._cached_radius = radius
        return radius

    def parameters(self) -> dict[str, float]:
        """The method's parameters, for reports."""
        return {}
