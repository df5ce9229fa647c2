"""Projection onto the constraint manifold (MATH.md 3.4): positions by M-weighted Gauss-Newton,
velocities by the M-weighted least-change projection. Redundancy-safe (least-squares Delassus solves).
A unilateral row is projected only while it is closed or penetrating (and, for velocities, approaching).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .errors import ProjectionError

if TYPE_CHECKING:
    from .model import ConstrainedModel

RCOND = 1e-12


def weighted_correction(inverse_mass: np.ndarray, jacobian: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """``-M^-1 J^T (J M^-1 J^T)^+ r``: the smallest kinetic-metric change that removes r to first order."""
    minv_jt = inverse_mass @ jacobian.T
    delassus = jacobian @ minv_jt
    return -minv_jt @ np.linalg.lstsq(delassus, residual, rcond=RCOND)[0]


def project_positions(
    model: ConstrainedModel,
    q: np.ndarray,
    t: float,
    inverse_mass: np.ndarray,
    tolerance: float,
    max_iterations: int,
) -> tuple[np.ndarray, int]:
    """Gauss-Newton on phi(q) = 0 from q; returns (q on the manifold, iterations).

    Raises:
        ProjectionError: the residual is still above ``tolerance`` (relative: see
            :meth:`~pinstab.model.ConstrainedModel.position_tolerance`) after ``max_iterations``.
    """
    threshold = model.position_tolerance(tolerance)
    for iteration in range(max_iterations + 1):
        values = model.constraint_values(q, np.zeros(model.nv), t)
        mask = model.constraints.enforced_positions(values.phi)
        phi = values.phi[mask]
        worst = float(np.max(np.abs(phi), initial=0.0))
        if worst <= threshold:
            return q, iteration
        if iteration == max_iterations or not np.isfinite(worst):
            break
        q = model.integrate(q, weighted_correction(inverse_mass, values.jacobian[mask], phi))
    raise ProjectionError(
        f"coordinate projection did not converge: residual {worst:.3g} after {max_iterations} iterations "
        f"at t = {t:.6g} s (tolerance {threshold:.1g}); the state is far from the constraint manifold or "
        "at a singular configuration. Reduce dt or use another method."
    )


def project_velocities(
    model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float, inverse_mass: np.ndarray
) -> np.ndarray:
    """``v - M^-1 G^T (G M^-1 G^T)^+ (G v + g_t)``: the consistent velocity nearest in kinetic metric
    (open or separating unilateral rows left out)."""
    values = model.constraint_values(q, v, t)
    rows = model.constraints.enforced_velocities(values)
    return v + weighted_correction(inverse_mass, values.jacobian[rows], values.velocity_residual[rows])
