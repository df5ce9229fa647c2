"""The internal (zero) dynamics of a servo run: the motion that the constraints, real and prescribed, leave
free, which the controls do not steer (docs/mathematics.md section 5).

The free directions are the null space Z of the stacked constraint Jacobian at the start; the free
coordinates that name them are the velocity coordinates a pivoted QR of Z^T picks (those Z moves most
independently). The zero dynamics linearized at the start, ``d/dt (z, dz) = A (z, dz)`` with ``A = [[0, I],
[Z^T da/dq Z, Z^T da/dv Z]]`` (the closed-loop accelerations differenced along Z, central, with the
velocity kept on the constraints), has eigenvalues [1/s]: a positive real part grows, purely imaginary ones
oscillate without damping, so nothing bounds what a time-varying target pumps in. Over the run the free
coordinates' speeds are measured; one that exceeds :data:`RUNAWAY_FACTOR` times its start speed (at least
:data:`REFERENCE_SPEED`) ran away: :class:`~pinstab.errors.ZeroDynamicsWarning` names it.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import pinocchio as pin
import scipy.linalg

from .errors import ZeroDynamicsWarning
from .system import ConstrainedSystem

RANK_TOLERANCE = 1e-9  # singular values of the constraint Jacobian below this times its largest count as zero
DIFFERENCE_STEP = 1e-6  # [rad or m, rad/s or m/s] of the central differences along Z
RUNAWAY_FACTOR = 10.0  # a free coordinate whose speed grows beyond this times its start speed ran away
REFERENCE_SPEED = 1.0  # [rad/s or m/s] the start speed counts as at least this
MARGINAL = 1e-6  # [1/s] real parts within this of zero count as zero (undamped)


def velocity_names(model: pin.Model) -> list[str]:
    """The name of each velocity coordinate: its joint's, with ``[k]`` for joints of several."""
    names = [""] * model.nv
    for joint, name in zip(model.joints[1:], model.names[1:], strict=True):
        for k in range(joint.nv):
            names[joint.idx_v + k] = name if joint.nv == 1 else f"{name}[{k}]"
    return names


def free_directions(jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Z, indices): an orthonormal basis (nv, m) of the null space of the constraint Jacobian, and the m
    velocity coordinates that parametrize it (pivoted QR of Z^T)."""
    nv = jacobian.shape[1]
    if jacobian.size == 0:
        return np.eye(nv), np.arange(nv)
    _, singular, right = np.linalg.svd(jacobian)
    rank = int(np.count_nonzero(singular > RANK_TOLERANCE * max(float(singular[0]), 1.0)))
    basis = right[rank:].T
    if basis.shape[1] == 0:
        return basis, np.zeros(0, dtype=int)
    pivots = scipy.linalg.qr(basis.T, pivoting=True, mode="r")[1]
    return basis, np.sort(pivots[: basis.shape[1]])


def linearized(system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, t: float, basis: np.ndarray) -> np.ndarray:
    """The 2m x 2m matrix A of the zero dynamics at (q [rad, m], v [rad/s, m/s], t [s]) in the coordinates
    along ``basis`` (Z), by central differences of the closed-loop accelerations [1/s^2, 1/s]."""
    model, count = system.model.model, basis.shape[1]

    def acceleration(q_: np.ndarray, v_: np.ndarray) -> np.ndarray:
        values = system.model.constraint_values(q_, v_, t)  # the constraints at q_, to put v_ back on them
        corrected = v_ - np.linalg.pinv(values.jacobian, rcond=1e-12) @ values.velocity_residual
        return system.dynamics(q_, corrected, t).acceleration

    h = DIFFERENCE_STEP
    by_position, by_velocity = np.zeros((count, count)), np.zeros((count, count))
    for j, direction in enumerate(basis.T):
        ahead, behind = pin.integrate(model, q, h * direction), pin.integrate(model, q, -h * direction)
        by_position[:, j] = basis.T @ (acceleration(ahead, v) - acceleration(behind, v)) / (2 * h)
        by_velocity[:, j] = (
            basis.T @ (acceleration(q, v + h * direction) - acceleration(q, v - h * direction)) / (2 * h)
        )
    return np.block([[np.zeros((count, count)), np.eye(count)], [by_position, by_velocity]])


def character(eigenvalues: np.ndarray) -> str:
    """``unstable`` (a real part > :data:`MARGINAL`), ``undamped`` (the largest within it of zero) or
    ``stable``; ``none`` without eigenvalues."""
    if eigenvalues.size == 0:
        return "none"
    largest = float(np.max(eigenvalues.real))
    return "unstable" if largest > MARGINAL else ("undamped" if largest > -MARGINAL else "stable")


def zero_dynamics_report(system: ConstrainedSystem, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> dict[str, Any]:
    """For a servo run's samples (t [s], q, v): the free coordinates, the eigenvalues [1/s] of the zero
    dynamics linearized at the first sample and their ``character``, and per free coordinate its speed at the
    start, its largest speed and when [rad/s or m/s, s], and whether it ran away; ``runaway`` lists those."""
    values = system.model.constraint_values(q[0], v[0], float(t[0]))
    basis, indices = free_directions(values.jacobian)
    eigenvalues = np.linalg.eigvals(linearized(system, q[0], v[0], float(t[0]), basis)) if indices.size else np.zeros(0)
    eigenvalues = eigenvalues[np.lexsort((eigenvalues.imag, -eigenvalues.real))]
    names = velocity_names(system.model.model)
    finite = np.isfinite(v).all(axis=1)
    coordinates = {}
    for index in indices:
        speeds = np.where(finite, np.abs(v[:, index]), -np.inf)
        worst = int(np.argmax(speeds))
        start = float(speeds[0])
        coordinates[names[index]] = {
            "start_speed": start,
            "max_speed": float(speeds[worst]),
            "at": float(t[worst]),
            "runaway": bool(speeds[worst] > RUNAWAY_FACTOR * max(start, REFERENCE_SPEED)),
        }
    return {
        "free_coordinates": list(coordinates),
        "eigenvalues_at_start": [[float(e.real), float(e.imag)] for e in eigenvalues],
        "character": character(eigenvalues),
        "coordinates": coordinates,
        "runaway": [name for name, entry in coordinates.items() if entry["runaway"]],
    }


def warn_runaway(report: dict[str, Any], scene: str) -> None:
    """:class:`~pinstab.errors.ZeroDynamicsWarning` naming the free coordinates of ``report`` that ran away,
    with their speeds and the zero dynamics' eigenvalues at the start."""
    if not report.get("runaway"):
        return
    ran = "; ".join(
        f"{name} reached {entry['max_speed']:.4g} at t = {entry['at']:.4g} s, from {entry['start_speed']:.3g} at t = 0"
        for name, entry in report["coordinates"].items()
        if entry["runaway"]
    )
    eigenvalues = ", ".join(f"{re:+.3g}" + (f"{im:+.3g}j" if im else "") for re, im in report["eigenvalues_at_start"])
    warnings.warn(
        ZeroDynamicsWarning(
            f"scene {scene}: free coordinates ran away (speeds in rad/s or m/s): {ran}. The servos hold their own "
            f"rows, not the motion they leave free (their zero dynamics), which no control steers; linearized at "
            f"the start it is {report['character']} (eigenvalues {eigenvalues} 1/s). Damp or actuate these "
            "coordinates, or start where the zero dynamics is stable"
        ),
        stacklevel=3,
    )
