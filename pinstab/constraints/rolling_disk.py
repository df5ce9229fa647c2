"""A thin disk (a wheel) rolling without slipping on a fixed world plane [MLS ex. 6.2] (docs/mathematics.md section 1).

The disk is a rigid circle of ``radius`` r centred at a frame's origin c, in the plane orthogonal to its
``axis`` a (world axes: ``a = R_c a_local``). Its contact point with the plane ``{x : n . (x - p0) = 0}``
is its point nearest the plane, ``p = c - r u`` with ``u`` the unit projection of the normal on the
disk's plane, ``u = (n - (n . a) a) / |n - (n . a) a|``. The material point of the disk at p moves with
``v_p = v_c + omega x (p - c) = v_c + r u x omega``, so its Jacobian is ``J_p = J_v + r [u]x J_omega``
(LOCAL_WORLD_ALIGNED frame Jacobian of c), and along any motion (``du/dt`` from ``da/dt = omega x a``)

    d v_p / dt = a_c + r (du/dt x omega + u x alpha),

``a_c``, ``alpha`` the classical linear and angular accelerations of frame c: at zero joint acceleration
this is the drift term of every row below.

Two kinds, one per row type:

* ``rolling-disk``: 2 Pfaffian (nonholonomic) rows, no slip: ``T v_p = 0`` with ``T`` the plane's
  tangents (t1, t2) of :func:`~pinstab.constraints.contacts.contact_basis`.
* ``disk-touch``: 1 holonomic row, the disk touches the plane:
  ``phi = n . (c - p0) - r sqrt(1 - (n . a)^2) = n . (p - p0)`` [m], whose Jacobian is ``n^T J_p``
  (the contact point slides over the disk, but its normal velocity is the material point's). It is a
  bilateral row: the disk cannot leave the plane.

A disk held upright and at its height by its joints (the MLS configuration (x, y, heading, spin)) needs
``rolling-disk`` only; a wheel that may tilt or lift (a free-flying coin, a wheel on a suspension) needs
both. The multipliers are the force of the plane on the disk at the contact point [N]: in (t1, t2) for
``rolling-disk``, along n for ``disk-touch``. A disk lying flat (axis along the normal) has no defined
contact point: :class:`~pinstab.errors.ConstraintError`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from ..errors import ConstraintError, SceneError
from ..kinematics import Kinematics
from ..tables import SceneTables, unit
from .base import CONSTRAINT_KINDS, Constraint, VelocityTerms
from .contacts import contact_basis
from .grasp_contacts import cross

DISK_KEYS = {"name", "kind", "frame", "offset", "axis", "radius", "normal", "point"}
FLAT_TOLERANCE = 1e-9  # |n - (n . a) a| below this: the disk lies flat, its contact point is undefined


class DiskPlaneContact(Constraint):
    """Rows of the velocity of the disk's material point at its contact with a plane (see the module).

    Args:
        name: unique name. frame: the operational frame at the disk's centre.
        axis: the disk's axis in that frame's axes (normalized here). radius: r [m].
        normal: the plane's unit normal, world axes (from the plane into the disk).
        point: a point of the plane, world [m].
        holonomic: ``disk-touch`` (1 row along the normal, with a residual) or ``rolling-disk`` (2 rows
            along the plane's tangents).
    """

    def __init__(
        self,
        name: str,
        frame: int,
        axis: np.ndarray,
        radius: float,
        normal: np.ndarray,
        point: np.ndarray,
        holonomic: bool,
    ) -> None:
        basis = contact_basis(normal)
        self.name = name
        self.frame = frame
        self.axis = unit(axis)
        self.radius = float(radius)
        self.normal = basis[0]
        self.point = np.asarray(point, dtype=float)
        self.holonomic = holonomic
        self.selection = basis[:1] if holonomic else basis[1:]
        self.rows = self.selection.shape[0]
        self.force_frame = (
            "plane normal n, force of the plane on the disk"
            if holonomic
            else "plane tangents (t1, t2), force of the plane on the disk at the contact"
        )

    def contact_direction(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray, float]:
        """(a, u, |w|): the world axis, the unit direction from the contact point to the centre, and
        ``|n - (n . a) a|`` (the sine of the angle between axis and normal). Placements must be current."""
        axis = kin.placement(self.frame).rotation @ self.axis
        towards = self.normal - float(self.normal @ axis) * axis
        size = float(np.linalg.norm(towards))
        if size < FLAT_TOLERANCE:
            raise ConstraintError(
                f"constraint {self.name}: the disk lies flat on the plane; its contact point is undefined"
            )
        return axis, towards / size, size

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        """``n . (p - p0)`` [m]: the height of the disk's lowest point over the plane (``disk-touch``)."""
        if not self.holonomic:
            return super().residual(kin, q, t)
        _, towards, _ = self.contact_direction(kin)
        contact = kin.placement(self.frame).translation - self.radius * towards
        return self.selection @ (contact - self.point)

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        """``(S J_p, 0)``: J_p the material contact point's Jacobian [m/rad, 1], S the row selection."""
        _, towards, _ = self.contact_direction(kin)
        jac = kin.jacobian(self.frame)
        material = jac[:3] + self.radius * pin.skew(towards) @ jac[3:]
        return VelocityTerms(self.selection @ material, np.zeros(self.rows))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """``S (a_c + r (du/dt x omega + u x alpha))`` at zero joint acceleration [m/s^2]."""
        axis, towards, size = self.contact_direction(kin)
        omega = kin.velocity(self.frame).angular
        acceleration = kin.drift_acceleration(self.frame)
        axis_rate = cross(omega, axis)
        towards_rate = self._direction_rate(axis, axis_rate, towards, size)
        rate = cross(towards_rate, omega) + cross(towards, acceleration.angular)
        return self.selection @ (acceleration.linear + self.radius * rate)

    def _direction_rate(self, axis: np.ndarray, axis_rate: np.ndarray, towards: np.ndarray, size: float) -> np.ndarray:
        """du/dt [1/s] of ``u = w / |w|``, ``w = n - (n . a) a``, given da/dt."""
        normal = self.normal
        w_rate = -float(normal @ axis_rate) * axis - float(normal @ axis) * axis_rate
        return (w_rate - towards * float(towards @ w_rate)) / size


def parse_disk(holonomic: bool) -> Callable[[dict, SceneTables, str, str], DiskPlaneContact]:
    """The scene-table reader of ``disk-touch`` (``holonomic``) or ``rolling-disk``: ``frame`` (the disk's
    centre, + ``offset`` [m] in it), ``axis`` in that frame (default y), ``radius`` [m], the plane's
    ``normal`` (default +z) and ``point`` [m] (default the origin)."""

    def parse(entry: dict, tables: SceneTables, name: str, where: str) -> DiskPlaneContact:
        tables.check_keys(entry, DISK_KEYS, where)
        if "radius" not in entry:
            raise SceneError(f"{where}: 'radius' is required")
        radius = tables.quantity(entry["radius"], "length", f"{where}.radius")
        if not radius > 0:
            raise SceneError(f"{where}.radius must be > 0, got {entry['radius']!r}")
        axis = tables.direction(entry.get("axis", [0.0, 1.0, 0.0]), f"{where}.axis")
        normal = tables.direction(entry.get("normal", [0.0, 0.0, 1.0]), f"{where}.normal")
        point = tables.vector(entry.get("point", [0.0, 0.0, 0.0]), 3, f"{where}.point", "length")
        frame = tables.attached_frame(entry, "frame", "offset", "rpy", f"{name}/centre", where)
        axis_start = tables.initial_placement(frame).rotation @ axis
        if np.linalg.norm(np.cross(normal, axis_start)) < FLAT_TOLERANCE:
            raise SceneError(
                f"{where}: the disk lies flat on the plane at the initial configuration (axis along normal)"
            )
        return DiskPlaneContact(name, frame, axis, radius, normal, point, holonomic)

    return parse


CONSTRAINT_KINDS.register(
    "rolling-disk",
    parse_disk(holonomic=False),
    summary="2 Pfaffian rows: a disk rolls on a world plane without slipping (contact point's tangential velocity)",
)
CONSTRAINT_KINDS.register(
    "disk-touch",
    parse_disk(holonomic=True),
    summary="1 holonomic row: a disk touches a world plane (its lowest point on the plane), for a disk that may tilt",
)
