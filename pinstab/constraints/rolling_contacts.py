"""Rolling fingertip contacts on a scene object [MLS ch. 5] (docs/mathematics.md section 4).

Kind ``rolling-contact``: the fingertip is a sphere of ``radius`` r [m] centred at the ``finger`` frame's
origin c; it rolls on the surface of ``object`` (a scene object) without slipping. The contact point is
where the sphere touches the surface now, p = c - r n (n the surface's outward unit normal at the point
nearest to c): it moves on both bodies, a function of the configuration. At the scene's start the finger's
joints close the gap, as for ``grasp-contact``; the shape the fingertip then touches is the surface it rolls
on for the whole run: a sphere, a box face or a cylinder's side or cap (a face or a cap is its plane: the
contact is not held back at its edges).

Rows, with w the velocity of c relative to the object's motion at c, Omega = omega_o - omega_f the object's
angular velocity relative to the finger, and the contact frame C (z the inward normal -n, x and y tangents
carried along with the normal, see :func:`transported_frame`):

* block ``NAME`` (holonomic, 1 row): the touching condition phi = d(c) - r = 0, d the signed distance from
  c to the surface [m]; its rate is n . w.
* block ``NAME/rolling`` (Pfaffian): no slip, x_C . Delta and y_C . Delta = 0, Delta = v_o(p) - v_f(p) the
  velocity of the object's material point at p relative to the fingertip's [m/s]; for ``soft-finger`` also
  no spin, z_C . Omega = 0 [rad/s].

The contact ``model`` picks the blocks by the wrench it transmits [MLS ch. 5]: ``frictionless`` the
touching condition only (the fingertip slides and rolls freely), ``point-friction`` (``mu``) adds no slip
(the fingertip may spin about the normal), ``soft-finger`` (``mu``, ``torsion``) also no spin. A rigid
contact cannot roll. The multipliers are the finger's force [N] on the object in C: the normal force
(block ``NAME``, >= 0 when it pushes: :class:`~pinstab.errors.GraspLostError` when it would have to pull),
then the tangential force and the moment about the normal [N m] (block ``NAME/rolling``, which checks them
with its touching block's normal force, its ``force_partners``: GraspLostError when the fingertip would
slide out of its friction cone or, a soft finger, spin).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import NamedTuple

import coal
import numpy as np
import pinocchio as pin

from ..contact.collisions import Touch
from ..contact.models import ContactLimits
from ..errors import ConstraintError, SceneError, choices
from ..kernels import contact_point_world_jacobian, contact_point_world_rate
from ..kinematics import Kinematics, PerUpdate
from ..tables import SceneTables
from .base import CONSTRAINT_KINDS, Constraint, VelocityTerms
from .grasp_contacts import close_gap, cross, read_coefficients, read_fingertip
from .loops import plane_basis

ROLLING_KEYS = {"name", "kind", "finger", "object", "model", "radius", "mu", "torsion"}
ROLLING_MODELS = ("frictionless", "point-friction", "soft-finger")
ANTIPODE_MARGIN = 1e-6  # 1 + cos(turn): the contact frame is undefined where the normal turned by pi


# -- surfaces ------------------------------------------------------------------------------------------
class Surface(ABC):
    """An object's surface, in the object frame: the signed distance d(x) [m] of a point x [m] from it,
    its gradient (the outward unit normal at the nearest surface point) and its Hessian [1/m]."""

    @abstractmethod
    def distance(self, x: np.ndarray) -> float:
        """d(x) [m]: > 0 outside the object."""

    @abstractmethod
    def normal(self, x: np.ndarray) -> np.ndarray:
        """The outward unit normal at the surface point nearest to x."""

    @abstractmethod
    def hessian(self, x: np.ndarray) -> np.ndarray:
        """d normal / dx (3 x 3, symmetric, normal in its kernel) [1/m]."""


@dataclass(frozen=True)
class SphereSurface(Surface):
    """A sphere of ``radius`` [m] about ``centre`` [m]."""

    centre: np.ndarray
    radius: float

    def distance(self, x: np.ndarray) -> float:
        return float(np.linalg.norm(x - self.centre)) - self.radius

    def normal(self, x: np.ndarray) -> np.ndarray:
        offset = x - self.centre
        return offset / np.linalg.norm(offset)

    def hessian(self, x: np.ndarray) -> np.ndarray:
        offset = x - self.centre
        length = float(np.linalg.norm(offset))
        normal = offset / length
        return (np.eye(3) - np.outer(normal, normal)) / length


@dataclass(frozen=True)
class PlaneSurface(Surface):
    """The plane through ``point`` [m] with the unit normal ``outward`` (a box face, a cylinder cap)."""

    point: np.ndarray
    outward: np.ndarray

    def distance(self, x: np.ndarray) -> float:
        return float(self.outward @ (x - self.point))

    def normal(self, x: np.ndarray) -> np.ndarray:
        return self.outward

    def hessian(self, x: np.ndarray) -> np.ndarray:
        return np.zeros((3, 3))


@dataclass(frozen=True)
class CylinderSide(Surface):
    """The side of a cylinder of ``radius`` [m] about the line through ``centre`` [m] along unit ``axis``."""

    centre: np.ndarray
    axis: np.ndarray
    radius: float

    def _radial(self, x: np.ndarray) -> np.ndarray:
        offset = x - self.centre
        return offset - (self.axis @ offset) * self.axis

    def distance(self, x: np.ndarray) -> float:
        return float(np.linalg.norm(self._radial(x))) - self.radius

    def normal(self, x: np.ndarray) -> np.ndarray:
        radial = self._radial(x)
        return radial / np.linalg.norm(radial)

    def hessian(self, x: np.ndarray) -> np.ndarray:
        radial = self._radial(x)
        length = float(np.linalg.norm(radial))
        normal = radial / length
        return (np.eye(3) - np.outer(self.axis, self.axis) - np.outer(normal, normal)) / length


def surface_of(shape: coal.CollisionGeometry, local: pin.SE3, centre: np.ndarray, where: str) -> Surface:
    """The surface of ``shape`` (placed at ``local`` in the object frame) that a fingertip centred at
    ``centre`` (object frame) [m] touches: the sphere, the box face or the cylinder side or cap facing it.

    Raises:
        SceneError: another shape, or the fingertip touches an edge or a corner.
    """
    inside = local.actInv(centre)  # the fingertip's centre in the shape's frame
    if isinstance(shape, coal.Sphere):
        return SphereSurface(local.translation.copy(), float(shape.radius))
    if isinstance(shape, coal.Box):
        beyond = np.abs(inside) > shape.halfSide
        if np.count_nonzero(beyond) != 1:
            raise SceneError(f"{where}: the fingertip touches the box at an edge or a corner; it can roll on a face")
        return _face(local, int(np.argmax(beyond)), float(np.sign(inside[beyond][0])), float(shape.halfSide[beyond][0]))
    if isinstance(shape, coal.Cylinder):
        radial, axial = float(np.hypot(inside[0], inside[1])), abs(float(inside[2]))
        if axial <= shape.halfLength and radial > shape.radius:
            return CylinderSide(local.translation.copy(), local.rotation[:, 2].copy(), float(shape.radius))
        if axial > shape.halfLength and radial <= shape.radius:
            return _face(local, 2, float(np.sign(inside[2])), float(shape.halfLength))
        raise SceneError(f"{where}: the fingertip touches the cylinder's rim; it can roll on its side or a cap")
    raise SceneError(
        f"{where}: the fingertip touches a {type(shape).__name__}; a rolling contact rolls on a sphere, a box face "
        "or a cylinder's side or cap"
    )


def _face(local: pin.SE3, axis: int, side: float, half: float) -> PlaneSurface:
    """The face of a box or cylinder at ``side`` (+1 or -1) ``half`` [m] along the shape's ``axis``."""
    outward = side * local.rotation[:, axis]
    return PlaneSurface(local.translation + half * outward, outward)


# -- the contact frame ---------------------------------------------------------------------------------
def transported_frame(start: np.ndarray, normal: np.ndarray, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The smallest rotation taking the unit vector ``start`` onto the unit vector ``normal`` and its rate
    when ``normal`` moves at ``rate`` (orthogonal to it): (R, dR/dt).

    R = E + [k] + [k]^2 / (1 + c) with k = start x normal, c = start . normal. Applied to a frame whose z
    is ``start`` it gives a frame whose z is ``normal``, smooth everywhere but at ``normal = -start``.
    """
    k, k_rate = cross(start, normal), cross(start, rate)
    c, c_rate = float(start @ normal), float(start @ rate)
    hat, hat_rate = pin.skew(k), pin.skew(k_rate)
    square = hat @ hat
    rotation = np.eye(3) + hat + square / (1.0 + c)
    rotation_rate = hat_rate + (hat_rate @ hat + hat @ hat_rate) / (1.0 + c) - square * c_rate / (1.0 + c) ** 2
    return rotation, rotation_rate


class ContactState(NamedTuple):
    """A rolling contact at one configuration, world axes.

    Attributes:
        axes: the contact frame C (columns x, y tangents, z the inward normal).
        offset: c - p_o, the fingertip centre from the object frame's origin [m].
        gap: phi = d(c) - r [m]. hessian: H, the Hessian of the signed distance at c (the rate of the outward
            normal per unit motion of c), world axes [1/m].
    """

    axes: np.ndarray
    offset: np.ndarray
    gap: float
    hessian: np.ndarray


class RollingGeometry:
    """The geometry both blocks of a rolling contact share.

    Args:
        surface: the object's surface (object frame). object_frame: the object's body frame.
        finger_frame: the frame at the fingertip sphere's centre. radius: the fingertip's radius [m].
        start: the contact frame C in the object frame at the start (columns x, y, z, z the inward normal).
        name: the contact, for messages.
    """

    def __init__(
        self, surface: Surface, object_frame: int, finger_frame: int, radius: float, start: np.ndarray, name: str
    ) -> None:
        self.surface, self.object_frame, self.finger_frame = surface, object_frame, finger_frame
        self.radius, self.start, self.name = radius, start, name
        # the two blocks ask for the state five times an evaluation, for the Jacobians and the rates twice
        self._state = PerUpdate(self._compute_state)
        self._jacobians = PerUpdate(lambda kin: self._compute_jacobians(kin, self.state(kin)))
        self._rates = PerUpdate(lambda kin: self._compute_rates(kin, self.state(kin)))

    def state(self, kin: Kinematics) -> ContactState:
        """The contact at the current placements (computed once per kinematics update)."""
        return self._state(kin)

    def _compute_state(self, kin: Kinematics) -> ContactState:
        placement = kin.placement(self.object_frame)
        centre = kin.placement(self.finger_frame).translation
        rotation = placement.rotation
        offset = centre - placement.translation
        local = rotation.T @ offset
        inward = -self.surface.normal(local)
        turn, _ = self._transport(inward, np.zeros(3))
        axes = rotation @ turn @ self.start
        hessian = rotation @ self.surface.hessian(local) @ rotation.T
        return ContactState(axes, offset, self.surface.distance(local) - self.radius, hessian)

    def _transport(self, inward: np.ndarray, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if 1.0 + float(self.start[:, 2] @ inward) < ANTIPODE_MARGIN:
            raise ConstraintError(
                f"rolling contact {self.name!r}: the contact normal has turned half a turn from its start; its "
                "contact frame is undefined there"
            )
        return transported_frame(self.start[:, 2], inward, rate)

    def axes_rate(self, kin: Kinematics, state: ContactState, centre: np.ndarray) -> np.ndarray:
        """dR_C/dt [1/s] given ``centre`` = w, the fingertip centre's velocity relative to the object's motion
        there (world) [m/s]."""
        rotation = kin.placement(self.object_frame).rotation
        omega = kin.velocity(self.object_frame).angular
        inward = rotation.T @ state.axes[:, 2]
        inward_rate = -rotation.T @ state.hessian @ centre  # object frame
        _, turn_rate = self._transport(inward, inward_rate)
        return pin.skew(omega) @ state.axes + rotation @ turn_rate @ self.start

    def normal_rate(self, kin: Kinematics, state: ContactState, centre: np.ndarray) -> np.ndarray:
        """dz_C/dt = omega_o x z_C - H w [1/s] given ``centre`` = w [m/s] (the third column of
        :meth:`axes_rate`, for less work)."""
        return cross(kin.velocity(self.object_frame).angular, state.axes[:, 2]) - state.hessian @ centre

    def jacobians(self, kin: Kinematics, state: ContactState) -> tuple[np.ndarray, np.ndarray]:
        """(J_w, J_Omega): w = J_w v, the fingertip centre's velocity relative to the object's motion there,
        and Omega = J_Omega v = omega_o - omega_f (3 x nv each, world axes); ``state`` is :meth:`state`'s
        (once per kinematics update, shared: not to be modified)."""
        return self._jacobians(kin)

    def _compute_jacobians(self, kin: Kinematics, state: ContactState) -> tuple[np.ndarray, np.ndarray]:
        # J_w = J_f - J_o + [c - p_o]x W_o: minus a fingertip contact's point rows in world axes (cpp/contact_terms.cpp)
        point = contact_point_world_jacobian(kin.model, kin.data, self.object_frame, self.finger_frame)
        return -point, kin.jacobian(self.object_frame)[3:] - kin.jacobian(self.finger_frame)[3:]

    def rates(self, kin: Kinematics, state: ContactState) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(w, dw/dt, Omega, dOmega/dt) at zero joint acceleration (world axes) [m/s, m/s^2, rad/s, rad/s^2];
        ``state`` is :meth:`state`'s (once per kinematics update, shared: not to be modified)."""
        return self._rates(kin)

    def _compute_rates(
        self, kin: Kinematics, state: ContactState
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        velocity_o, velocity_f = kin.velocity(self.object_frame), kin.velocity(self.finger_frame)
        acc_o, acc_f = kin.drift_acceleration(self.object_frame), kin.drift_acceleration(self.finger_frame)
        omega_o = velocity_o.angular
        linear = velocity_f.linear - velocity_o.linear
        # w = v_f - v_o - omega_o x (c - p_o): minus the point rows' rate in world axes (cpp/contact_terms.cpp)
        centre = -contact_point_world_rate(kin.model, kin.data, self.object_frame, self.finger_frame)
        # dw/dt at zero joint acceleration (world axes; not the point rows' drift, d2/dt2 of R_o^T (p_o - p_f))
        centre_rate = acc_f.linear - acc_o.linear - cross(acc_o.angular, state.offset) - cross(omega_o, linear)
        return centre, centre_rate, omega_o - velocity_f.angular, acc_o.angular - acc_f.angular

    def contact_points(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """The contact point p = c - r n [m] in the object frame and in the finger frame. Placements must
        be current."""
        point = kin.placement(self.finger_frame).translation + self.radius * self.state(kin).axes[:, 2]
        return kin.placement(self.object_frame).actInv(point), kin.placement(self.finger_frame).actInv(point)


# -- the two blocks ------------------------------------------------------------------------------------
class RollingTouch(Constraint):
    """The touching condition of a rolling contact: 1 holonomic row phi = d(c) - r [m]; its multiplier is
    the finger's normal force on the object [N] (along C's z), checked to push."""

    holonomic = True
    rows = 1
    limits_force = True

    def __init__(self, name: str, geometry: RollingGeometry, limits: ContactLimits) -> None:
        self.name, self.kind, self.geometry, self.limits = name, "rolling-contact", geometry, limits
        self.force_frame = "contact frame C's z (the inward normal): normal force of finger on object"
        self.touch = Touch(name, geometry.finger_frame, geometry.object_frame, at_point=False)

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return np.array([self.geometry.state(kin).gap])

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        state = self.geometry.state(kin)
        centre, _ = self.geometry.jacobians(kin, state)
        return VelocityTerms(-state.axes[:, 2:].T @ centre, np.zeros(1))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        state = self.geometry.state(kin)
        centre, centre_rate, _, _ = self.geometry.rates(kin, state)
        normal_rate = self.geometry.normal_rate(kin, state, centre)
        return np.array([-(normal_rate @ centre) - state.axes[:, 2] @ centre_rate])

    def margins(self, force: np.ndarray) -> dict[str, float]:
        """``normal``: the normal force f_n [N] (>= 0: it pushes)."""
        return self.limits.margins(np.array([0.0, 0.0, force[0], 0.0, 0.0, 0.0]))

    def check_force(self, force: np.ndarray, t: float) -> None:
        """Raise :class:`~pinstab.errors.GraspLostError` when the fingertip would have to pull."""
        self.limits.check(np.array([0.0, 0.0, force[0], 0.0, 0.0, 0.0]), t)


class RollingNoSlip(Constraint):
    """The Pfaffian rows of a rolling contact: no slip (x_C . Delta, y_C . Delta [m/s]) and, with
    ``spin`` False, no spin (z_C . Omega [rad/s]). Multipliers: the finger's tangential force on the object
    [N] along C's x and y, then its moment about C's z [N m]. Checked with the touching block's normal
    force (its force partner): inside the friction cone, and the soft finger's moment within its limit."""

    holonomic = False
    limits_force = True

    def __init__(self, name: str, geometry: RollingGeometry, spin: bool, touch: str, limits: ContactLimits) -> None:
        self.name, self.kind, self.geometry, self.spin = name, "rolling-contact", geometry, spin
        self.force_partners, self.limits = (touch,), limits
        self.rows = 2 if spin else 3
        self.force_frame = "contact frame C (x, y tangents, z inward normal): force and moment of finger on object"

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        state = self.geometry.state(kin)
        centre, relative = self.geometry.jacobians(kin, state)
        # Delta = v_o(p) - v_f(p) = -w - r z x Omega
        slip = -centre - self.geometry.radius * pin.skew(state.axes[:, 2]) @ relative
        rows = state.axes[:, :2].T @ slip
        if not self.spin:
            rows = np.vstack([rows, state.axes[:, 2] @ relative])
        return VelocityTerms(rows, np.zeros(self.rows))

    def _wrench(self, force: np.ndarray) -> np.ndarray:
        """(fx, fy, fz, mx, my, mz) in C from (normal force, the block's own multipliers)."""
        moment = force[3] if len(force) > 3 else 0.0
        return np.array([force[1], force[2], force[0], 0.0, 0.0, moment])

    def margins(self, force: np.ndarray) -> dict[str, float]:
        """``normal`` [N], ``friction`` mu f_n - |f_t| [N], soft finger ``torsion`` [N m] (>= 0: held) of
        (the touching block's normal force, this block's multipliers)."""
        return self.limits.margins(self._wrench(force))

    def check_force(self, force: np.ndarray, t: float) -> None:
        """Raise :class:`~pinstab.errors.GraspLostError` when the fingertip would slide or spin."""
        self.limits.check(self._wrench(force), t)

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        state = self.geometry.state(kin)
        centre, centre_rate, relative, relative_rate = self.geometry.rates(kin, state)
        axes_rate = self.geometry.axes_rate(kin, state, centre)
        normal, normal_rate, radius = state.axes[:, 2], axes_rate[:, 2], self.geometry.radius
        slip = -centre - radius * cross(normal, relative)
        slip_rate = -centre_rate - radius * (cross(normal_rate, relative) + cross(normal, relative_rate))
        rows = axes_rate[:, :2].T @ slip + state.axes[:, :2].T @ slip_rate
        if self.spin:
            return rows
        return np.append(rows, normal_rate @ relative + normal @ relative_rate)


# -- scene table ---------------------------------------------------------------------------------------
def parse_rolling_contact(entry: dict, tables: SceneTables, name: str, where: str) -> list[Constraint]:
    """Scene table: ``finger`` (a frame at the fingertip sphere's centre), ``object`` (a scene object),
    ``model`` (``frictionless``, ``point-friction`` (default) or ``soft-finger``), ``radius`` [m] of the
    fingertip sphere, ``mu`` for ``point-friction`` / ``soft-finger``, ``torsion`` [m] for ``soft-finger``.
    The blocks ``name`` (touching) and, with friction, ``name/rolling`` (no slip, no spin)."""
    tables.check_keys(entry, ROLLING_KEYS, where)
    model_name = entry.get("model", "point-friction")
    if model_name not in ROLLING_MODELS:
        rigid = " (a rigid contact cannot roll)" if model_name == "rigid" else ""
        raise SceneError(
            f"{where}: a rolling contact's model is one of {choices(ROLLING_MODELS)}, got {model_name!r}{rigid}"
        )
    fingertip = read_fingertip(entry, tables, where)
    mu, torsion = read_coefficients(entry, tables, model_name, where)
    nearest = close_gap(tables, fingertip, where)
    object_placement = tables.initial_placement(fingertip.item.frame)
    centre = object_placement.actInv(tables.initial_placement(fingertip.frame).translation)
    surface = surface_of(nearest.shape, nearest.local, centre, where)
    inward = -surface.normal(centre)
    start = np.column_stack([*plane_basis(inward), inward])
    geometry = RollingGeometry(surface, fingertip.item.frame, fingertip.frame, fingertip.radius, start, name)
    touch = RollingTouch(
        name, geometry, ContactLimits(name, "frictionless", mu, torsion, fingertip.name, fingertip.item.name)
    )
    if model_name == "frictionless":
        return [touch]
    limits = ContactLimits(name, model_name, mu, torsion, fingertip.name, fingertip.item.name)
    return [touch, RollingNoSlip(f"{name}/rolling", geometry, model_name == "point-friction", name, limits)]


CONSTRAINT_KINDS.register(
    "rolling-contact",
    parse_rolling_contact,
    summary="a fingertip sphere rolling on an object: touching (1 holonomic row), no slip (2), no spin (soft-finger)",
)
