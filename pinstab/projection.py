"""Projection onto the constraint manifold (docs/mathematics.md 3.4): positions by M-weighted Gauss-Newton,
velocities by the M-weighted least-change projection. Redundancy-safe (the Delassus matrix's pseudo-inverse).
A unilateral row is projected only while it is closed or penetrating (and, for velocities, approaching).

The rules are compiled once (``cpp/projection.cpp``): the least-change correction (:func:`weighted_correction`), the
Gauss-Newton iteration with its stopping rule (:func:`project_positions`) and the corrections of ``projection`` and
``post`` (:func:`correct`) take any :class:`Projector`'s two projections: :class:`GeneralProjector` from pinstab's
rows, :class:`pinstab.paths.native.NativeProjector` from Pinocchio's algorithms,
:class:`pinstab.paths.banded.BandedProjector` from the banded solve (each called back from C++), and
:class:`pinstab.paths.core.CoreProjector`, the core kernel's rows evaluated in C++ (no Python call); with those the
compiled step loop corrects each of its steps (:func:`loop_correction`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

from . import kernels
from .errors import ProjectionError

if TYPE_CHECKING:
    from .kinematics import Kinematics
    from .model import ConstrainedModel

CUTOFF = 1e-12  # the Delassus matrix's eigenvalues at most this times its largest are left out of its pseudo-inverse
ROUNDING_RESIDUAL = 16  # ulps of the mechanism's size: a residual this small is rounding
NOT_CONVERGED, NOT_FINITE = 1, 2  # the compiled corrections' outcomes besides 0, done


def weighted_correction(
    mass: np.ndarray, jacobian: np.ndarray, residual: np.ndarray, refine: bool = False
) -> np.ndarray:
    """``-M^-1 G^T (G M^-1 G^T)^+ r``: the smallest kinetic-metric change that removes r to first order (M [kg,
    kg m^2], G, r [m or rad, or m/s or rad/s]; the pseudo-inverse's :data:`CUTOFF`). ``refine``: where near-singular
    rows leave more than rounding of r (their eigenvalues in G M^-1 G^T below the cutoff), refined by the singular
    values of the rows' square root ``G L^-T`` (M = L L^T; ``cpp/projection.hpp`` LeastChange).

    Raises:
        ProjectionError: M is not positive definite or the rows are not finite.
    """
    change, finite = kernels.weighted_correction(mass, jacobian, residual, CUTOFF, refine)
    if not finite:
        raise not_finite()
    return change


def not_finite() -> ProjectionError:
    """The error of a projection whose rows, their G M^-1 G^T or the mass matrix are not finite (or M not positive
    definite)."""
    return ProjectionError(
        "projection failed: the constraint rows are not finite or overflow (G M^-1 G^T), or the mass matrix is not "
        "finite or not positive definite"
    )


class Projector(Protocol):
    """The projections a post-step correction is made of, on one path (general or native). A projector that can
    refine its least change on near-singular rows (:func:`weighted_correction`'s ``refine``) has a method
    ``refine(on: bool) -> None`` too, which the position projection calls where D's pseudo-inverse alone does not
    converge (``cpp/projection.hpp`` project_positions)."""

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
        self.refining = False

    def refine(self, on: bool) -> None:
        """Refine both projections' least change from now on (:func:`weighted_correction`'s ``refine``), or not."""
        self.refining = on

    def position_step(self, q: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        model = self.model
        values = model.constraint_values(q, np.zeros(model.nv), t)
        mask = model.constraints.enforced_positions(values.phi)
        phi = values.phi[mask]
        worst = float(np.max(np.abs(phi), initial=0.0))
        return weighted_correction(model.mass_matrix(q), values.jacobian[mask], phi, self.refining), worst

    def velocity_projection(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        model = self.model
        return project_velocities(model, q, v, t, model.mass_matrix(q), refine=self.refining)


def tolerances(model: ConstrainedModel, tolerance: float) -> tuple[float, float]:
    """The position projection's threshold for the relative ``tolerance`` (see
    :meth:`~pinstab.model.ConstrainedModel.position_tolerance`) and the residual that is rounding [m or rad]."""
    return model.position_tolerance(tolerance), ROUNDING_RESIDUAL * model.position_tolerance(np.finfo(float).eps)


def _refuse(outcome: int, worst: float, max_iterations: int, t: float, threshold: float) -> None:
    """Raise the ProjectionError of a compiled correction's ``outcome`` (not 0, done)."""
    if outcome == NOT_FINITE:
        raise not_finite()
    raise ProjectionError(
        f"coordinate projection did not converge: residual {worst:.3g} after {max_iterations} iterations "
        f"at t = {t:.6g} s (tolerance {threshold:.1g}); the state is far from the constraint manifold or "
        "at a singular configuration. Reduce dt or use another method."
    )


def compiled_projections(projector: Projector) -> kernels.CoreProjection | None:
    """The projector's projections evaluated in C++ (:class:`pinstab.paths.core.CoreProjector`'s), or None."""
    return getattr(projector, "compiled", None)


def _compiled(projector: Projector) -> object:
    """What the compiled corrections take for ``projector``: its compiled projections where it has them (the core's),
    else the projector itself (its methods called back)."""
    compiled = compiled_projections(projector)
    return projector if compiled is None else compiled


def loop_correction(
    model: ConstrainedModel, projector: Projector, post: bool, tolerance: float = 0.0, max_iterations: int = 1
) -> kernels.CoreCorrection:
    """The correction :func:`correct` makes, made by the compiled step loop after each of its steps
    (``cpp/step_loop.hpp``) with the projector's compiled projections (:func:`compiled_projections`, which it has);
    a correction that cannot be made stops the loop before that step (:func:`correct` then says why)."""
    threshold, floor = tolerances(model, tolerance)
    return kernels.CoreCorrection(compiled_projections(projector), post, threshold, floor, max_iterations)


def project_positions(
    model: ConstrainedModel,
    projector: Projector,
    q: np.ndarray,
    t: float,
    tolerance: float,
    max_iterations: int,
) -> tuple[np.ndarray, int]:
    """Gauss-Newton on phi(q) = 0 from q at t [s] (``cpp/projection.cpp`` project_positions); returns (q on the
    manifold, iterations).

    Converged means near the manifold, not a small residual: where the Jacobian is close to losing
    rank (a singular configuration, where two branches of the manifold cross) the residual grows only
    quadratically with the distance across them, so a residual of eps leaves q about sqrt(eps) off its
    branch. The iteration therefore stops when its last step (the distance to the manifold, to first
    order) is below the threshold, with the residual below it too; or when the residual is at rounding
    level (:data:`ROUNDING_RESIDUAL`) or the steps stop contracting (rounding then decides them, not the
    constraints).

    Raises:
        ProjectionError: the residual is still above ``tolerance`` (relative: see
            :meth:`~pinstab.model.ConstrainedModel.position_tolerance`) after ``max_iterations``.
    """
    threshold, floor = tolerances(model, tolerance)
    q, iterations, worst, outcome = kernels.project_positions(
        _compiled(projector), model.model, threshold, floor, max_iterations, q, t
    )
    if outcome:
        _refuse(outcome, worst, max_iterations, t, threshold)
    return q, iterations


def correct(
    model: ConstrainedModel,
    projector: Projector,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    post: bool,
    tolerance: float = 0.0,
    max_iterations: int = 1,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The correction of the state (q, v) reached at t [s] (``cpp/projection.cpp`` correct): ``projection`` (post
    False: :func:`project_positions` to ``tolerance`` in ``max_iterations``, then the velocities projected at the
    projected q) or ``post`` (one Gauss-Newton step and the velocity projection, both at the uncorrected state);
    returns (q, v, iterations).

    Raises:
        ProjectionError: the position projection did not converge, or the rows are not finite.
    """
    threshold, floor = tolerances(model, tolerance)
    q, v, iterations, worst, outcome = kernels.correct(
        _compiled(projector), model.model, post, threshold, floor, max_iterations, q, v, t
    )
    if outcome:
        _refuse(outcome, worst, max_iterations, t, threshold)
    return q, v, iterations


def project_velocities(
    model: ConstrainedModel,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    mass: np.ndarray,
    kin: Kinematics | None = None,
    touching: float = 0.0,
    refine: bool = False,
) -> np.ndarray:
    """``v - M^-1 G^T (G M^-1 G^T)^+ (G v + g_t)``: the consistent velocity nearest in kinetic metric
    (open or separating unilateral rows left out; open: a gap above ``touching`` [m or rad]); ``mass``: M(q) [kg,
    kg m^2]; ``kin``: as in :meth:`ConstrainedModel.constraint_values`; ``refine``: as in
    :func:`weighted_correction`."""
    values = model.constraint_values(q, v, t, kin)
    rows = model.constraints.enforced_velocities(values, touching)
    return v + weighted_correction(mass, values.jacobian[rows], values.velocity_residual[rows], refine)
