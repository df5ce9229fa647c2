"""``projection`` (coordinate + velocity projection after every step) and ``post``
(Ascher, Chin, Petzold & Reich 1995: one correction per step with the projector evaluated once).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import PinstabError
from ..projection import project_positions, project_velocities, weighted_correction
from .base import Correction, Stabilizer

if TYPE_CHECKING:
    from ..system import ConstrainedSystem


class ProjectionStabilizer(Stabilizer):
    """Project q onto phi = 0 by Gauss-Newton, then v onto G v + g_t = 0, after every step.

    Args:
        tolerance: position residual to reach [m or rad].
        max_iterations: Gauss-Newton iterations before :class:`~pinstab.errors.ProjectionError`.
    """

    name = "projection"

    def __init__(self, tolerance: float = 1e-13, max_iterations: int = 20) -> None:
        if not tolerance > 0 or max_iterations < 1:
            raise PinstabError("projection: tolerance must be > 0 and max_iterations >= 1")
        self.tolerance, self.max_iterations = tolerance, max_iterations

    def correct(self, system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, t: float) -> Correction:
        inverse_mass = np.linalg.inv(system.mass_matrix(q))
        q, iterations = project_positions(system, q, t, inverse_mass, self.tolerance, self.max_iterations)
        return Correction(q, project_velocities(system, q, v, t, inverse_mass), iterations)

    def parameters(self) -> dict[str, float]:
        return {"tolerance": self.tolerance, "max_iterations": self.max_iterations}


class PostStabilizer(Stabilizer):
    """One post-stabilization step: ``q <- q (+) (-F phi)``, ``v <- v - F g`` with
    ``F = M^-1 G^T (G M^-1 G^T)^+`` evaluated once, at the uncorrected state."""

    name = "post"

    def correct(self, system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, t: float) -> Correction:
        values = system.constraint_values(q, v, t)
        inverse_mass = np.linalg.inv(system.mass_matrix(q))
        mask = system.constraints.holonomic_mask
        q_new = system.integrate(q, weighted_correction(inverse_mass, values.jacobian[mask], values.phi[mask]))
        v_new = v + weighted_correction(inverse_mass, values.jacobian, values.velocity_residual)
        return Correction(q_new, v_new, 1)
