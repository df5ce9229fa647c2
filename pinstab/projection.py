"""Projection onto the constraint manifold (docs/mathematics.md 3.4): positions by M-weighted Gauss-Newton,
velocities by the M-weighted least-change projection. Redundancy-safe (least-squares Delassus solves).
A unilateral row is projected only while it is closed or penetrating (and, for velocities, approaching).

A :class:`Projector` gives the two projections on one path: :class:`GeneralProjector` from pinstab's
rows, :class:`pinstab.paths.native.NativeProjector` from Pinocchio's algorithms,
:class:`pinstab.paths.banded.BandedProjector` from the banded solve.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

from .errors import ProjectionError

if TYPE_CHECKING:
    from .kinematics import Kinematics
    from .model import ConstrainedModel

RCOND = 1e-12
ROUNDING_RESIDUAL = 16  # ulps of the mechanism's size: a residual this small is rounding
CONTRACTION = 0.5  # Gauss-Newton steps that shrink less than this per iteration are rounding-dominated


def weighted_correction(inverse_mass: np.ndarray, jacobian: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """``-M^-1 J^T (J M^-1 J^T)^+ r``: the smallest kinetic-metric change that removes r to first order."""
    minv_jt = inverse_mass @ jacobian.T
    delassus = jacobian @ minv_jt
    try:
        return -minv_jt @ np.linalg.lstsq(delassus, residual, rcond=RCOND)[0]
    except np.linalg.LinAlgError as exc:  # non-finite or overflowing rows: the state is beyond repair
        raise ProjectionError(f"projection failed: the constraint rows are not finite ({exc})") from None


class Projector(Protocol):
    """The projections a post-step correction is made of, on one path (general or native)."""

    def position_step(self, q: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        """The M-weighted Gauss-Newton step ``dq = -M^-1 G^T (G M^-1 G^T)^+ phi`` at q and max |phi|
        there [m or rad] (enforced rows only)."""
        ...

    def velocity_projection(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """``v - M^-1 G^T (G M^-1 G^T)^+ (G v + g_t)`` at q [m/s or rad/s]."""
        ...


class GeneralProjector:
    """Projections from pinstab's constraint rows (any constraint kind; unilateral rows only while
    closed or approaching).

    Args:
        model: the constrained model.
    """

    def __init__(self, model: ConstrainedModel) -> None:
        self.model = model

    def position_step(self, q: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        model = self.model
        values = model.constraint_values(q, np.zeros(model.nv), t)
        mask = model.constraints.enforced_positions(values.phi)
        phi = values.phi[mask]
        worst = float(np.max(np.abs(phi), initial=0.0))
        inverse_mass = np.linalg.inv(model.mass_matrix(q))
        return weighted_correction(inverse_mass, values.jacobian[mask], phi), worst

    def velocity_projection(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        model = self.model
        return project_velocities(model, q, v, t, np.linalg.inv(model.mass_matrix(q)))


def project_positions(
    model: ConstrainedModel,
    projector: Projector,
    q: np.ndarray,
    t: float,
    tolerance: float,
    max_iterations: int,
) -> tuple[np.ndarray, int]:
    """Gauss-Newton on phi(q) = 0 from q; returns (q on the manifold, iterations).

    Converged means near the manifold, not a small residual: where the Jacobian is close to losing
    rank (a singular configuration, where two branches of the manifold cross) the residual grows only
    quadratically with the distance across them, so a residual of eps leaves q about sqrt(eps) off its
    branch. The iteration therefore stops when its last step (the distance to the manifold, to first
    order) is below the threshold, with the residual below it too; or when the residual is at rounding
    level or the steps stop contracting (rounding then decides them, not the constraints).

    Raises:
        ProjectionError: the residual is still above ``tolerance`` (relative: see
            :meth:`~pinstab.model.ConstrainedModel.position_tolerance`) after ``max_iterations``.
    """
    threshold = model.position_tolerance(tolerance)
    floor = ROUNDING_RESIDUAL * model.position_tolerance(np.finfo(float).eps)
    previous = np.inf
    for iteration in range(max_iterations + 1):
        step, worst = projector.position_step(q, t)
        if not np.isfinite(worst):
            break
        size = float(np.max(np.abs(step), initial=0.0))
        if worst <= threshold and (worst <= floor or size > CONTRACTION * previous):
            return q, iteration
        if iteration == max_iterations:
            break
        q = model.integrate(q, step)
        if worst <= threshold and size <= threshold:
            return q, iteration + 1
        previous = size
    raise ProjectionError(
        f"coordinate projection did not converge: residual {worst:.3g} after {max_iterations} iterations "
        f"at t = {t:.6g} s (tolerance {threshold:.1g}); the state is far from the constraint manifold or "
        "at a singular configuration. Reduce dt or use another method."
    )


def project_velocities(
    model: ConstrainedModel,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    inverse_mass: np.ndarray,
    kin: Kinematics | None = None,
    touching: float = 0.0,
) -> np.ndarray:
    """``v - M^-1 G^T (G M^-1 G^T)^+ (G v + g_t)``: the consistent velocity nearest in kinetic metric
    (open or separating unilateral rows left out; open: a gap above ``touching`` [m or rad]); ``kin``: as in
    :meth:`ConstrainedModel.constraint_values`."""
    values = model.constraint_values(q, v, t, kin)
    rows = model.constraints.enforced_velocities(values, touching)
    return v + weighted_correction(inverse_mass, values.jacobian[rows], values.velocity_residual[rows])
