"""Assembly: the configuration nearest the given one that satisfies the closures, then the
consistent velocity (MATH.md section 1, eq. 1)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from .errors import AssemblyError
from .projection import project_velocities

if TYPE_CHECKING:
    from .system import ConstrainedSystem


@dataclass
class AssemblyReport:
    """Result of :func:`assemble`.

    Attributes:
        q, v: consistent configuration and velocity.
        iterations: Levenberg-Marquardt iterations.
        residual: final max |phi| [m or rad].
        velocity_residual: final max |G v + g_t| [m/s or rad/s].
        displacement: norm of the configuration change from the given q (tangent space).
    """

    q: np.ndarray
    v: np.ndarray
    iterations: int
    residual: float
    velocity_residual: float
    displacement: float


def assemble(
    system: ConstrainedSystem,
    q: np.ndarray,
    v: np.ndarray,
    t: float = 0.0,
    tolerance: float = 1e-12,
    max_iterations: int = 200,
) -> AssemblyReport:
    """Levenberg-Marquardt on phi(q) = 0 with minimum-norm steps (redundancy-safe), then the
    kinetic-metric projection of v onto ``G v + g_t = 0``.

    Raises:
        AssemblyError: the closures cannot be met (the message names the worst closure and its
            residual), e.g. link lengths that cannot close.
    """
    q_start = q.copy()
    mask = system.constraints.holonomic_mask
    damping = 1e-6
    phi, jac = _residual(system, q, t, mask)
    cost = float(phi @ phi)
    iterations = 0
    while iterations < max_iterations and np.max(np.abs(phi), initial=0.0) > tolerance:
        iterations += 1
        step = -jac.T @ np.linalg.solve(jac @ jac.T + damping * np.eye(len(phi)), phi)
        trial = system.integrate(q, step)
        trial_phi, trial_jac = _residual(system, trial, t, mask)
        trial_cost = float(trial_phi @ trial_phi)
        if np.isfinite(trial_cost) and trial_cost < cost:
            q, phi, jac, cost = trial, trial_phi, trial_jac, trial_cost
            damping = max(damping / 10.0, 1e-15)
        else:
            damping *= 10.0
            if damping > 1e8:
                break
    residual = float(np.max(np.abs(phi), initial=0.0))
    if residual > tolerance:
        worst = _worst_constraint(system, phi, mask)
        raise AssemblyError(
            f"assembly failed: the closures cannot be met from the given configuration; residual "
            f"{residual:.3g} (largest on closure {worst!r}) after {iterations} iterations. Check the link "
            "lengths and closure offsets, or start from a configuration nearer a closed one.",
            residual,
        )
    v = project_velocities(system, q, v, t, np.linalg.inv(system.mass_matrix(q)))
    velocity_residual = float(np.max(np.abs(system.constraint_values(q, v, t).velocity_residual), initial=0.0))
    displacement = float(np.linalg.norm(pin.difference(system.model, q_start, q)))
    return AssemblyReport(q, v, iterations, residual, velocity_residual, displacement)


def _residual(system: ConstrainedSystem, q: np.ndarray, t: float, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    values = system.constraint_values(q, np.zeros(system.nv), t)
    return values.phi[mask], values.jacobian[mask]


def _worst_constraint(system: ConstrainedSystem, phi: np.ndarray, mask: np.ndarray) -> str:
    full = np.zeros(system.constraints.rows)
    full[mask] = phi
    worst_row = int(np.argmax(np.abs(full)))
    for name, rows in system.constraints.slices.items():
        if rows.start <= worst_row < rows.stop:
            return name
    return "?"
