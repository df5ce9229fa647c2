"""The contact problem with torsion rows solved in NumPy: the second method the compiled solve (cpp/torsion_cone.hpp,
``ConeSolver.solve_torsion``) is checked against, through the reference step
(:class:`~pinstab.bench.python_stepper.PythonStepper`).

The problem (D, g) has rows (t1, t2, n) per contact, then one row per contact whose torsion length c > 0 [m] (its
relative angular velocity about the normal), in contact order; the law is the product of the round cone
``|lambda_t| <= mu lambda_n`` and the torsion interval ``|lambda_tau| <= c lambda_n`` with De Saxce's velocity
``sigma_n + mu |sigma_t| + c |sigma_tau|`` (the event modes' law: each friction at its bound against its slip). The
same iteration as the compiled one (Pinocchio's ADMM in NCP mode, on the rows scaled to a unit diagonal and steep
cones scaled to 1), computed another way: LAPACK's eigenvalues and Cholesky factor, the projection by NumPy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ..solvers.ncp import ncp_residual

TAU, PROXIMAL, RHO_POWER, RHO_POWER_FACTOR, RATIO = 0.5, 1e-6, 0.2, 0.05, 10.0  # Pinocchio's ADMM defaults
RHO_MIN, RHO_MAX = 1e-6, 1e6


def torsion_rows(torsions: Sequence[float]) -> list[int | None]:
    """Each contact's torsion row (None: no torsion) in the layout of the module."""
    rows: list[int | None] = []
    following = 3 * len(torsions)
    for torsion in torsions:
        rows.append(following if torsion > 0.0 else None)
        following += torsion > 0.0
    return rows


def projection(x: np.ndarray, mu: float, torsion: float) -> np.ndarray:
    """The nearest point of x (t1, t2, n, tau) to ``|t| <= mu n``, ``|tau| <= torsion n``: n minimizes ``(n -
    x_n)^2 + (|x_t| - mu n)_+^2 + (|x_tau| - torsion n)_+^2`` over n >= 0 (each term's friction cut to its bound)."""
    tangential, normal, spin = math.hypot(x[0], x[1]), x[2], abs(x[3])
    if tangential <= mu * normal and spin <= torsion * normal and normal >= 0.0:
        return x.copy()
    breaks = {"slip": tangential / mu if mu > 0.0 else math.inf, "spin": spin / torsion if torsion > 0.0 else math.inf}
    cut = {"slip": True, "spin": True}

    def slope(n: float) -> float:
        return n - normal - mu * max(tangential - mu * n, 0.0) - torsion * max(spin - torsion * n, 0.0)

    for name in sorted(breaks, key=breaks.get):  # the root lies beyond every breakpoint where the slope is < 0
        if breaks[name] < math.inf and slope(breaks[name]) < 0.0:
            cut[name] = False
        else:
            break
    pull = normal + (mu * tangential if cut["slip"] else 0.0) + (torsion * spin if cut["spin"] else 0.0)
    along = max(pull, 0.0) / (1.0 + (mu * mu if cut["slip"] else 0.0) + (torsion * torsion if cut["spin"] else 0.0))
    shrink = (mu * along / tangential if tangential > 0.0 else 0.0) if cut["slip"] else 1.0
    return np.array(
        [x[0] * shrink, x[1] * shrink, along, math.copysign(torsion * along, x[3]) if cut["spin"] else x[3]]
    )


def _parts(x: np.ndarray, rows: list[int | None]) -> list[np.ndarray]:
    """Each contact's (t1, t2, n, tau) of a vector of the layout (tau 0 without a torsion row)."""
    return [np.array([*x[3 * i : 3 * i + 3], 0.0 if r is None else x[r]]) for i, r in enumerate(rows)]


def _joined(parts: list[np.ndarray], rows: list[int | None], size: int) -> np.ndarray:
    """The vector of the layout made of each contact's (t1, t2, n, tau)."""
    x = np.zeros(size)
    for i, (part, r) in enumerate(zip(parts, rows, strict=True)):
        x[3 * i : 3 * i + 3] = part[:3]
        if r is not None:
            x[r] = part[3]
    return x


def _project(x: np.ndarray, mus: np.ndarray, torsions: np.ndarray, rows: list[int | None]) -> np.ndarray:
    parts = [projection(p, mu, c) for p, mu, c in zip(_parts(x, rows), mus, torsions, strict=True)]
    return _joined(parts, rows, x.size)


def _desaxce(sigma: np.ndarray, mus: np.ndarray, torsions: np.ndarray, rows: list[int | None]) -> np.ndarray:
    out = sigma.copy()
    for i, (mu, c, r) in enumerate(zip(mus, torsions, rows, strict=True)):
        out[3 * i + 2] += mu * math.hypot(sigma[3 * i], sigma[3 * i + 1]) + c * (0.0 if r is None else abs(sigma[r]))
    return out


def _scales(
    delassus: np.ndarray, mus: np.ndarray, torsions: np.ndarray, rows: list[int | None]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rows' scales (each to a unit diagonal, steep cones to 1) and the scaled mus and torsions."""
    diagonal = np.diag(delassus)

    def unit(value: float) -> float:
        return 1.0 / math.sqrt(value) if value > 0.0 else 1.0

    scales, mus_scaled, torsions_scaled = np.ones(diagonal.size), mus.astype(float), torsions.astype(float)
    for i, r in enumerate(rows):
        normal, tangent = unit(diagonal[3 * i + 2]), unit(0.5 * (diagonal[3 * i] + diagonal[3 * i + 1]))
        mus_scaled[i] = mus[i] * normal / tangent
        if mus_scaled[i] > 1.0:
            tangent, mus_scaled[i] = tangent * mus_scaled[i], 1.0
        scales[3 * i : 3 * i + 3] = tangent, tangent, normal
        if r is not None:
            turn = unit(diagonal[r])
            torsions_scaled[i] = torsions[i] * normal / turn
            if torsions_scaled[i] > 1.0:
                turn, torsions_scaled[i] = turn * torsions_scaled[i], 1.0
            scales[r] = turn
    return scales, mus_scaled, torsions_scaled


def torsion_admm(
    delassus: np.ndarray,
    g: np.ndarray,
    mus: Sequence[float],
    torsions: Sequence[float],
    tolerance: float,
    max_iterations: int,
) -> tuple[np.ndarray, int]:
    """The impulses of the problem (D, g) (the module's layout) with friction coefficients ``mus`` [-] and torsion
    lengths ``torsions`` [m], and the iterations taken: ADMM until :func:`~pinstab.solvers.ncp.ncp_residual` is within
    ``tolerance`` of the velocity scale, or ``max_iterations`` (unchecked: the caller checks)."""
    mus, torsions = np.asarray(mus, dtype=float), np.asarray(torsions, dtype=float)
    rows = torsion_rows(torsions)
    scales, mus_s, torsions_s = _scales(delassus, mus, torsions, rows)
    scaled = scales[:, None] * delassus * scales
    matrix, gs = 0.5 * (scaled + scaled.T), scales * g
    largest = max(float(np.linalg.eigvalsh(matrix)[-1]), 2.0 * PROXIMAL)
    increment = (largest / PROXIMAL) ** RHO_POWER_FACTOR
    rho = min(max(math.sqrt(largest * PROXIMAL) * (largest / PROXIMAL) ** RHO_POWER, RHO_MIN), RHO_MAX)
    identity = np.eye(g.size)
    factor = cho_factor(matrix + (TAU * rho + PROXIMAL) * identity)
    x, z = np.zeros(g.size), _desaxce(gs, mus_s, torsions_s, rows)
    velocity_scale = float(np.max(np.abs(g), initial=0.0))
    for iteration in range(1, max_iterations + 1):
        x_previous, z_previous = x, z
        y = _project(x - z / (TAU * rho), mus_s, torsions_s, rows)
        correction = _desaxce(z_previous, mus_s, torsions_s, rows) - z_previous
        x = cho_solve(factor, -(gs + correction - (TAU * rho) * y - PROXIMAL * x_previous - z_previous))
        z = z_previous - (TAU * rho) * (x - y)
        impulses = scales * y
        scale = max(velocity_scale, float(np.max(np.abs(delassus @ impulses), initial=0.0)))
        if ncp_residual(delassus, g, impulses, mus, torsions) <= tolerance * scale:
            return impulses, iteration
        primal = float(np.max(np.abs(x - y)))
        dual = max(PROXIMAL, TAU * rho) * float(np.max(np.abs(x - x_previous)))
        following = rho * increment if primal > RATIO * dual else rho / increment if dual > RATIO * primal else rho
        following = min(max(following, RHO_MIN), RHO_MAX)
        if following != rho:
            rho = following
            factor = cho_factor(matrix + (TAU * rho + PROXIMAL) * identity)
    return impulses, max_iterations
