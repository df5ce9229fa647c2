"""Assembly: the configuration nearest the given one that satisfies the closures, then the
consistent velocity (docs/mathematics.md section 1, eq. 1).

The residual accepted is relative to the mechanism's size L (:func:`mechanism_size`): a closure residual up
to ``tolerance * L`` [m or rad] is accepted, :data:`DEFAULT_TOLERANCE` unless ``assemble(tolerance=...)``,
``simulate(assembly_tol=...)``, ``--assembly-tol`` or the scene's ``[assembly] tolerance`` say otherwise; a
loop closed to 1e-10 of its length (at most L) is accepted by default.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from .errors import AssemblyError, PinstabError, ProjectionError
from .projection import project_velocities
from .runinfo import AssemblySummary
from .validation import relative_tolerance, singular_mass_error

if TYPE_CHECKING:
    from .model import ConstrainedModel

DEFAULT_TOLERANCE = 1e-10  # [-] the residual assembly accepts, relative to the mechanism's size
TARGET = 1e-12  # [-] the residual the iteration aims at, relative to max(1 m, the largest offset): rounding
MIN_SIZE = 1e-3  # [m] the size of a mechanism whose joints and frames all sit at one point


@dataclass
class AssemblyReport:
    """Result of :func:`assemble`.

    Attributes:
        q, v: consistent configuration and velocity.
        iterations: Levenberg-Marquardt iterations.
        residual: final max ``|phi|`` in each row's own units [m or rad] (a joint relation's residual over its
            largest coefficient).
        velocity_residual: final max ``|G v + g_t|`` [m/s or rad/s].
        displacement: norm of the configuration change from the given q (tangent space).
        tolerance: the largest residual accepted [m or rad] (the relative tolerance times the size).
        size: the mechanism's size L [m] (:func:`mechanism_size`).
    """

    q: np.ndarray
    v: np.ndarray
    iterations: int
    residual: float
    velocity_residual: float
    displacement: float
    tolerance: float
    size: float

    def summary(self) -> AssemblySummary:
        """The figures a run reports (without the state)."""
        return AssemblySummary(
            self.iterations, self.residual, self.velocity_residual, self.displacement, self.tolerance, self.size
        )


def mechanism_size(model: ConstrainedModel, q: np.ndarray) -> float:
    """The mechanism's size L [m]: the diagonal of the axis-aligned box holding the world origins of every joint
    and frame (closure and contact frames included) at configuration q, at least :data:`MIN_SIZE` (a
    mechanism whose joints all sit at one point). It bounds the length of every loop of the model."""
    data = model.scratch
    pin.framesForwardKinematics(model.model, data, q)
    points = np.array([m.translation for m in (*data.oMi, *data.oMf)])
    with np.errstate(over="ignore", invalid="ignore"):  # an overflowing offset: refused by the residual check
        diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
    return max(diagonal, MIN_SIZE) if np.isfinite(diagonal) else np.inf


def accepted_residual(model: ConstrainedModel, q: np.ndarray, tolerance: float | None) -> tuple[float, float, float]:
    """(relative tolerance [-], size L [m], the residual accepted [m or rad]) of an assembly from q:
    ``tolerance``, else the scene's ``[assembly] tolerance``, else :data:`DEFAULT_TOLERANCE`.

    Raises:
        SceneError: a tolerance that is not a number in (0, 1) (negative, zero, NaN, ...).
    """
    if tolerance is None:
        tolerance = model.scene.assembly_tolerance
    relative = relative_tolerance(DEFAULT_TOLERANCE if tolerance is None else tolerance, "the assembly tolerance")
    size = mechanism_size(model, q)
    return relative, size, relative * size


@np.errstate(over="ignore", invalid="ignore")  # overflowing rows end in an AssemblyError naming them
def assemble(
    model: ConstrainedModel,
    q: np.ndarray,
    v: np.ndarray,
    t: float = 0.0,
    tolerance: float | None = None,
    max_iterations: int = 200,
) -> AssemblyReport:
    """Levenberg-Marquardt on phi(q) = 0 with minimum-norm steps (redundancy-safe), then the
    kinetic-metric projection of v onto ``G v + g_t = 0``.

    Each row's residual is taken in its block's own units (:attr:`Constraint.residual_units`: a joint relation's
    over its largest coefficient for the tolerance, over its smallest for the aim at rounding), and each block's
    rows are scaled by their largest Jacobian row at the start for the step: the assembled q is the same whatever
    factor a relation's coefficients are written with (z2 + 1e9 z1 = 0 next to y2 - y1 = 0 no longer drowns the
    second).

    The iteration aims at rounding (:data:`TARGET`), or stops when it no longer progresses (a loop that cannot
    close exactly, e.g. offsets off by 2e-11 m out of the plane of a planar loop); the configuration is accepted
    when its largest residual is at most ``tolerance`` times the mechanism's size L (:func:`mechanism_size` at
    the given q).

    Args:
        tolerance: the accepted residual relative to L [-], in (0, 1); None: the scene's
            ``[assembly] tolerance``, else :data:`DEFAULT_TOLERANCE` (1e-10).

    Raises:
        AssemblyError: the closures cannot be met (the message names the worst closure, its residual and the
            tolerance), e.g. link lengths that cannot close.
        SceneError: a tolerance that is not a number in (0, 1).
    """
    q_start = q.copy()
    relative, size, accepted = accepted_residual(model, q, tolerance)
    threshold = min(model.position_tolerance(TARGET), accepted)
    mask = model.constraints.holonomic_mask
    units = model.constraints.residual_units[mask, 0]
    gearing = units / model.constraints.residual_units[mask, 1]  # phi * gearing: the residual the iteration aims at
    phi, jac = _residual(model, q, t, mask, units)
    # each block's rows scaled by their largest Jacobian row at the start, and the damping relative to that: the
    # step, and the point of the manifold it reaches, depend neither on the units nor on the scale of a block's rows
    scales = _block_scales(jac, _blocks(model, mask))
    damping = 1e-6
    cost = float(phi @ phi)
    iterations = 0
    while iterations < max_iterations and np.max(np.abs(phi * gearing), initial=0.0) > threshold:
        iterations += 1
        scaled = jac / scales[:, None]
        try:
            step = -scaled.T @ np.linalg.solve(scaled @ scaled.T + damping * np.eye(len(phi)), phi / scales)
        except np.linalg.LinAlgError:  # rows that overflow: the residual check below names the closure
            break
        trial = model.integrate(q, step)
        trial_phi, trial_jac = _residual(model, trial, t, mask, units)
        trial_cost = float(trial_phi @ trial_phi)
        if np.isfinite(trial_cost) and trial_cost < cost:
            q, phi, jac, cost = trial, trial_phi, trial_jac, trial_cost
            damping = max(damping / 10.0, 1e-15)
        else:
            damping *= 10.0
            if damping > 1e8:
                break
    residual = float(np.max(np.abs(phi), initial=0.0))
    if not residual <= accepted:  # NaN too
        worst = _worst_constraint(model, phi, mask)
        raise AssemblyError(
            f"assembly failed: the closures cannot be met from the given configuration; residual "
            f"{residual:.3g} m or rad (largest on closure {worst!r}) after {iterations} iterations, above the "
            f"tolerance {accepted:.3g} (relative tolerance {relative:g} times the mechanism's size {size:.3g} m). "
            "Check the link lengths and closure offsets, start from a configuration nearer a closed one, or accept "
            "a larger residual (--assembly-tol, [assembly] tolerance, assembly_tol).",
            residual,
        )
    mass = _mass(model, q)
    try:
        # the iteration closes unilateral rows too (held contacts touch at the start): one it left a rounding
        # open still holds, else a start velocity into it would be kept and sink the body; refined where rows are
        # near-singular (cassie kicked at its knee motor kept 5e-6 m/s on its shin-spring triangles without)
        v = project_velocities(model, q, v, t, mass, model.scratch_kinematics, accepted, refine=True)
    except ProjectionError:
        v = np.full(model.nv, np.nan)  # the rows or the velocity overflow: refused below
    rates = model.constraint_values(q, v, t, model.scratch_kinematics).velocity_residual
    velocity_residual = float(np.max(np.abs(rates), initial=0.0))
    if not (np.all(np.isfinite(v)) and np.isfinite(velocity_residual)):
        worst = _worst_constraint(model, np.where(np.isfinite(rates), rates, np.inf), np.ones(len(rates), bool))
        raise AssemblyError(
            f"assembly failed: the initial velocity made consistent with the constraints is not finite (worst on "
            f"constraint {worst!r}); check initial.v and the constraints' offsets for values too large for floating "
            "point",
            residual,
        )
    displacement = float(np.linalg.norm(model.difference(q_start, q)))
    return AssemblyReport(q, v, iterations, residual, velocity_residual, displacement, accepted, size)


def _mass(model: ConstrainedModel, q: np.ndarray) -> np.ndarray:
    """M(q) [kg, kg m^2], positive definite (its Cholesky factors exist); a singular mass matrix is a SceneError
    naming the joints that move no mass."""
    mass = model.mass_matrix(q)
    try:
        np.linalg.cholesky(mass)
    except np.linalg.LinAlgError:
        raise singular_mass_error(model.scene.model, mass, "the assembled configuration") from None
    return mass


def _residual(
    model: ConstrainedModel, q: np.ndarray, t: float, mask: np.ndarray, units: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(phi, G) on the rows of ``mask``, both divided by the rows' ``units``: phi in each block's own units [m or
    rad] (a joint relation's residual over its largest coefficient)."""
    values = model.constraint_values(q, np.zeros(model.nv), t, model.scratch_kinematics)
    return values.phi[mask] / units, values.jacobian[mask] / units[:, None]


def _blocks(model: ConstrainedModel, mask: np.ndarray) -> list[slice]:
    """Each holonomic block's rows among the rows of ``mask``."""
    position = np.cumsum(mask) - mask  # index of each row among the masked ones
    return [
        slice(int(position[rows.start]), int(position[rows.start]) + rows.stop - rows.start)
        for rows in model.constraints.slices.values()
        if rows.stop > rows.start and mask[rows.start]
    ]


def _block_scales(jac: np.ndarray, blocks: list[slice]) -> np.ndarray:
    """Per row, the largest Jacobian row norm of its block (1 for a block whose rows are all zero, or overflow)."""
    norms = np.linalg.norm(jac, axis=1)
    scales = np.ones(len(norms))
    for rows in blocks:
        largest = float(np.max(norms[rows]))
        if 0.0 < largest < np.inf:
            scales[rows] = largest
    return scales


def _worst_constraint(model: ConstrainedModel, phi: np.ndarray, mask: np.ndarray) -> str:
    if not model.constraints.rows:
        return "?"
    full = np.zeros(model.constraints.rows)
    full[mask] = phi
    worst_row = int(np.argmax(np.abs(full)))
    for name, rows in model.constraints.slices.items():
        if rows.start <= worst_row < rows.stop:
            return name
    return "?"


def perturbed_start(model: ConstrainedModel, size: float) -> tuple[np.ndarray, np.ndarray]:
    """The scene's assembled start, moved ``size`` [rad or m] off the manifold: (q, v) for a run
    with ``assemble_initial=False`` that shows how a method repairs a violation."""
    start = assemble(model, model.scene.q0, model.scene.v0)
    return perturbed_configuration(model, start.q, size), start.v


def perturbed_configuration(model: ConstrainedModel, q: np.ndarray, size: float) -> np.ndarray:
    """q moved ``size`` [rad or m, tangent-space norm] off the constraint manifold.

    The displacement is along ``G^T 1`` (normalized), a direction that changes every constraint row
    to first order and has no component along the manifold.
    """
    jac = model.constraint_values(q, np.zeros(model.nv), 0.0).jacobian
    direction = jac.T @ np.ones(jac.shape[0])
    norm = np.linalg.norm(direction)
    if norm == 0.0:
        raise PinstabError("the scene has no constraint rows to perturb")
    return model.integrate(q, size * direction / norm)
