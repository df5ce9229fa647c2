"""The dynamics of contacts in given modes (:mod:`pinstab.contact.modes`): one linear solve per state.

Contact i touches a fixed plane with normal n_i; its basis B_i has rows (n, t1, t2) (world axes), its
point's Jacobian J_i (3 x nv, world-aligned) and drift ``c_i = dJ_i/dt v``. Unknowns: the accelerations
a and the contact forces f_i = (f_n, f_t1, f_t2) on the body in B_i; ``M a + h = tau + sum J_i^T B_i^T f_i``
and per contact, by mode:

* sticking: ``B_i (J_i a + c_i) = -Kd B_i J_i v - Kp e_i`` (3 rows; e_i: the gap, then the tangential
  creep from the point where sticking began);
* sliding: ``n.(J_i a + c_i) = -Kd n.J_i v - Kp gap`` and ``f_t + mu f_n d = 0`` (d: the unit slip
  velocity, or while it is below :data:`SLIP_FLOOR` the direction the slip started in);
* separated: ``f_i = 0``.

With ``a = M^-1 (tau - h + W^T f)`` the rows are a 3k x 3k system in f, solved in the least-squares sense
with the smallest forces (redundant sticking contacts, e.g. a box on four corners, leave the forces
non-unique and the accelerations unique). Whether the forces can also lie inside every cone is decided by
:func:`cone_margin` (the best margin over the forces that give the same motion).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from ..contact.modes import Mode
from ..model import ConstrainedModel

SLIP_FLOOR = 1e-9  # [m/s] below this slip speed the slip direction is the one it started in
RANK_TOLERANCE = 1e-12  # relative singular values of the force system below this: redundant rows


@dataclass
class PlaneContactGeometry:
    """A body point touching a fixed plane.

    Attributes:
        name: the contact's name. frame: the operational frame at the point. basis: rows (n, t1, t2) [-].
        origin: a point of the plane [m]. mu: friction coefficient [-]. restitution: Newton's e [-].
        radius: a sphere of this radius [m] centred at the frame touches the plane (0: the frame's origin).
        anchor: where a sticking contact holds the point [m] (set when it starts sticking).
    """

    name: str
    frame: int
    basis: np.ndarray
    origin: np.ndarray
    mu: float
    restitution: float
    radius: float = 0.0
    anchor: np.ndarray = field(default_factory=lambda: np.zeros(3))


class ContactKinematics(NamedTuple):
    """The contacts at one state, in their bases: gaps (k,) [m], point positions (k, 3) [m, world],
    velocities (k, 3) [m/s, basis], Jacobians (3k, nv) [basis] and drifts (3k,) [m/s^2, basis]."""

    gaps: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    jacobian: np.ndarray
    drift: np.ndarray


class ModeSolution(NamedTuple):
    """Accelerations [m/s^2, rad/s^2], the contact forces (k, 3) [N, basis], the free accelerations
    (without contact forces), M^-1 W^T (nv, 3k), and the kinematics they were computed at."""

    acceleration: np.ndarray
    forces: np.ndarray
    free: np.ndarray
    mobility: np.ndarray
    contacts: ContactKinematics


class ModeDynamics:
    """Accelerations of a model whose plane contacts are in given modes.

    Args:
        model: the constrained model (its own constraints are equality rows solved the same way: not
            supported here yet, the scene's contacts only). contacts: the plane contacts.
        kp, kd: Baumgarte's gains on the contact rows [1/s^2], [1/s].

    Attributes:
        modes: each contact's mode. directions: the slip direction (t1, t2) each sliding contact started
            in. evaluations: solves so far.
    """

    def __init__(self, model: ConstrainedModel, contacts: list[PlaneContactGeometry], kp: float, kd: float) -> None:
        self.model = model
        self.contacts = contacts
        self.kp, self.kd = kp, kd
        self.modes: list[Mode] = [Mode.SEPARATED] * len(contacts)
        self.directions: list[np.ndarray] = [np.array([1.0, 0.0]) for _ in contacts]
        self.evaluations = 0

    def kinematics(self, q: np.ndarray, v: np.ndarray) -> ContactKinematics:
        """The contacts' gaps, velocities, Jacobians and drifts at (q, v) (a full kinematics pass)."""
        self.model.kin.update(q, v)
        return self.kinematics_from_kin(v)

    def slip_direction(self, i: int, velocity: np.ndarray) -> np.ndarray:
        """The unit slip direction (t1, t2) of contact i at its basis velocity ``velocity``."""
        slip = velocity[1:]
        speed = math.hypot(slip[0], slip[1])
        return slip / speed if speed > SLIP_FLOOR else self.directions[i]

    def solve(self, q: np.ndarray, v: np.ndarray, t: float, modes: list[Mode] | None = None) -> ModeSolution:
        """The accelerations and contact forces at (q, v, t) with the contacts in ``modes`` (default: theirs)."""
        modes = self.modes if modes is None else modes
        self.evaluations += 1
        model = self.model
        terms = model.dynamics_terms(q, v, t)
        contacts = self.kinematics_from_kin(v)
        solved = np.linalg.solve(terms.mass_matrix, np.column_stack([terms.tau - terms.bias, contacts.jacobian.T]))
        free, mobility = solved[:, 0], solved[:, 1:]
        size = 3 * len(self.contacts)
        if size == 0:
            return ModeSolution(free, np.zeros((0, 3)), free, mobility, contacts)
        system, rhs = np.zeros((size, size)), np.zeros(size)
        delassus = contacts.jacobian @ mobility
        reach = contacts.jacobian @ free + contacts.drift  # the contact accelerations without forces
        for i, (contact, mode) in enumerate(zip(self.contacts, modes, strict=True)):
            rows = slice(3 * i, 3 * i + 3)
            n = 3 * i
            if mode is Mode.SEPARATED:
                system[rows, rows] = np.eye(3)
                continue
            velocity = contacts.velocities[i]
            error = np.array([contacts.gaps[i], *(contact.basis[1:] @ (contacts.positions[i] - contact.anchor))])
            target = -reach[rows] - self.kd * velocity - self.kp * error
            if mode is Mode.STICKING:
                system[rows] = delassus[rows]
                rhs[rows] = target
                continue
            system[n] = delassus[n]
            rhs[n] = target[0]
            direction = self.slip_direction(i, velocity)
            system[n + 1 : n + 3, n + 1 : n + 3] = np.eye(2)
            system[n + 1 : n + 3, n] = contact.mu * direction
        forces = _least_norm(system, rhs)
        acceleration = free + mobility @ forces
        return ModeSolution(acceleration, forces.reshape(-1, 3), free, mobility, contacts)

    def kinematics_from_kin(self, v: np.ndarray) -> ContactKinematics:
        """:meth:`kinematics` from the pass :meth:`ConstrainedModel.dynamics_terms` just made."""
        kin = self.model.kin
        k = len(self.contacts)
        gaps, positions, velocities = np.zeros(k), np.zeros((k, 3)), np.zeros((k, 3))
        jacobian, drift = np.zeros((3 * k, self.model.nv)), np.zeros(3 * k)
        for i, contact in enumerate(self.contacts):
            rows = slice(3 * i, 3 * i + 3)
            normal, frame = contact.basis[0], contact.frame
            frame_jacobian, frame_drift = kin.jacobian(frame), kin.drift_acceleration(frame)
            positions[i] = kin.placement(frame).translation - contact.radius * normal
            point_jacobian, point_drift = frame_jacobian[:3], frame_drift.linear
            if contact.radius:  # the touching point of the sphere: v_c + omega x (-r n)
                arm = contact.radius * pin.skew(normal)
                point_jacobian = point_jacobian + arm @ frame_jacobian[3:]
                point_drift = point_drift + arm @ frame_drift.angular
            jacobian[rows] = contact.basis @ point_jacobian
            velocities[i] = jacobian[rows] @ v
            drift[rows] = contact.basis @ point_drift
            gaps[i] = normal @ (positions[i] - contact.origin)
        return ContactKinematics(gaps, positions, velocities, jacobian, drift)

    def acceleration(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        """The accelerations at (q, v, t) in the current modes [m/s^2, rad/s^2] (the integrators' call)."""
        return self.solve(q, v, t).acceleration


def _least_norm(system: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The smallest x minimizing |system x - rhs| (redundant rows give a singular system)."""
    try:
        solution = np.linalg.solve(system, rhs)
        if np.isfinite(solution).all() and np.linalg.cond(system) < 1.0 / RANK_TOLERANCE:
            return solution
    except np.linalg.LinAlgError:
        pass
    return np.linalg.lstsq(system, rhs, rcond=RANK_TOLERANCE)[0]


def plane_geometries(constraints: list) -> list[PlaneContactGeometry]:
    """The plane contacts among a scene's constraints, as geometries for the event-driven dynamics."""
    from ..constraints import PointContact
    from ..constraints.contacts import contact_basis

    geometries = []
    for constraint in constraints:
        if isinstance(constraint, PointContact):
            basis = contact_basis(constraint.selection[0])
            mu = 0.0 if constraint.friction is None else constraint.friction.mu
            geometries.append(
                PlaneContactGeometry(
                    constraint.name,
                    constraint.frame_a,
                    basis,
                    constraint.plane_point.copy(),
                    mu,
                    constraint.restitution,
                    constraint.radius,
                )
            )
    return geometries
