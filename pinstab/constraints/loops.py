"""Loop closures between two frames, or a frame and a fixed world placement.

Kinds: ``point`` (3 rows, world axes), ``planar-point`` (2 rows: the point difference projected on
the two axes of a stated plane), ``weld`` (6 rows: point difference in world axes, then the
relative rotation ``log3(R_b^T R_a)``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..errors import ConstraintError, SceneError, choices
from ..kinematics import Kinematics
from ..tables import SceneTables, closure_frames, unit
from .base import CONSTRAINT_KINDS, Constraint, VelocityTerms

CLOSURE_KINDS = ("point", "planar-point", "weld")
CLOSURE_KEYS = {"name", "kind", "frame_a", "offset_a", "rpy_a", "frame_b", "offset_b", "rpy_b"}
PLANES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


def plane_basis(plane: str | np.ndarray) -> np.ndarray:
    """2 x 3 orthonormal basis of a plane given by name (``xy``, ``xz``, ``yz``) or normal."""
    if isinstance(plane, str):
        if plane not in PLANES:
            raise ConstraintError(f"unknown plane {plane!r}; valid planes: {choices(PLANES)} or a normal vector")
        return np.eye(3)[list(PLANES[plane])]
    normal = np.asarray(plane, dtype=float).reshape(-1)
    if normal.shape != (3,) or not np.all(np.isfinite(normal)) or not np.any(normal):
        raise ConstraintError(f"plane normal must be a non-zero 3-vector, got {plane!r}")
    normal = unit(normal)
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    first = np.cross(normal, helper)
    first /= np.linalg.norm(first)
    return np.vstack([first, np.cross(normal, first)])


class FrameClosure(Constraint):
    """A loop closure between frame ``a`` and frame ``b`` (or the world when ``frame_b`` is None).

    The frames are operational frames that the scene adds at the closure points, so the residual is
    ``p_a - p_b`` with both points in world coordinates [m]. The multipliers are the force [N]
    (and for ``weld`` the moment [N m]) that the closure exerts on body ``a``, in world axes
    (moment rows: in the axes of the relative rotation's log, i.e. frame a at closure); body ``b``
    receives the opposite.
    """

    holonomic = True

    def __init__(
        self,
        name: str,
        kind: str,
        frame_a: int,
        frame_b: int | None,
        world_placement_b: pin.SE3 | None = None,
        plane: str | np.ndarray = "xy",
    ) -> None:
        if kind not in CLOSURE_KINDS:
            raise ConstraintError(f"closure {name}: unknown kind {kind!r}; valid kinds: {choices(CLOSURE_KINDS)}")
        self.name = name
        self.kind = kind
        self.frame_a = frame_a
        self.frame_b = frame_b
        self.world_placement_b = world_placement_b if world_placement_b is not None else pin.SE3.Identity()
        self.selection = plane_basis(plane) if kind == "planar-point" else np.eye(3)
        self.locks_rotation = kind == "weld"  # rotation rows after the point rows
        self.rows = 6 if kind == "weld" else self.selection.shape[0]
        self.force_frame = (
            "world axes (force on a) + log3(R_b^T R_a) axes (moment on a)"
            if kind == "weld"
            else ("world axes, force on a" if kind == "point" else "plane axes, force on a")
        )

    def sides(self, model: pin.Model) -> tuple[tuple[int, pin.SE3], tuple[int, pin.SE3]]:
        """Where the closure's two points sit in ``model``: (joint, placement in the joint's frame) of side a and
        of side b, side b on the world as joint 0 at :attr:`world_placement_b`."""
        frame_a = model.frames[self.frame_a]
        if self.frame_b is None:
            return (frame_a.parentJoint, frame_a.placement), (0, self.world_placement_b)
        frame_b = model.frames[self.frame_b]
        return (frame_a.parentJoint, frame_a.placement), (frame_b.parentJoint, frame_b.placement)

    # -- helpers -----------------------------------------------------------------------------
    def _placement_b(self, kin: Kinematics) -> pin.SE3:
        return self.world_placement_b if self.frame_b is None else kin.placement(self.frame_b)

    def _relative_jacobian(self, kin: Kinematics) -> np.ndarray:
        jac = kin.jacobian(self.frame_a)
        if self.frame_b is not None:
            jac = jac - kin.jacobian(self.frame_b)
        return jac

    # -- Constraint ------------------------------------------------------------------------------
    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        oma, omb = kin.placement(self.frame_a), self._placement_b(kin)
        linear = self.selection @ (oma.translation - omb.translation)
        if not self.locks_rotation:
            return linear
        return np.concatenate([linear, pin.log3(omb.rotation.T @ oma.rotation)])

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        jac = self._relative_jacobian(kin)
        linear = self.selection @ jac[:3]
        if not self.locks_rotation:
            return VelocityTerms(linear, np.zeros(self.rows))
        oma, omb = kin.placement(self.frame_a), self._placement_b(kin)
        rel = omb.rotation.T @ oma.rotation
        angular = pin.Jlog3(rel) @ oma.rotation.T @ jac[3:]
        return VelocityTerms(np.vstack([linear, angular]), np.zeros(self.rows))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        acc_a = kin.drift_acceleration(self.frame_a)
        lin, ang = acc_a.linear.copy(), acc_a.angular.copy()
        if self.frame_b is not None:
            acc_b = kin.drift_acceleration(self.frame_b)
            lin -= acc_b.linear
            ang -= acc_b.angular
        linear = self.selection @ lin
        if not self.locks_rotation:
            return linear
        return np.concatenate([linear, self._rotation_drift(kin, ang)])

    def _rotation_drift(self, kin: Kinematics, relative_angular_drift: np.ndarray) -> np.ndarray:
        """The rotation rows' drift (:func:`rotation_drift`) at the current kinematics."""
        omega_b = kin.velocity(self.frame_b).angular if self.frame_b is not None else np.zeros(3)
        return rotation_drift(
            kin.placement(self.frame_a).rotation,
            self._placement_b(kin).rotation,
            kin.velocity(self.frame_a).angular,
            omega_b,
            relative_angular_drift,
        )


def rotation_drift(
    rotation_a: np.ndarray,
    rotation_b: np.ndarray,
    omega_a: np.ndarray,
    omega_b: np.ndarray,
    relative_angular_drift: np.ndarray,
) -> np.ndarray:
    """gamma0 of the rows ``log3(R_b^T R_a)`` [rad/s^2]: d/dt [Jlog3(R) R_a^T] (w_a - w_b) + Jlog3(R) R_a^T
    (alpha_a - alpha_b) at zero joint acceleration; omegas [rad/s] and ``relative_angular_drift`` (alpha_a -
    alpha_b) [rad/s^2] in world axes."""
    rel = rotation_b.T @ rotation_a
    relative_omega = omega_a - omega_b
    body_rate = rotation_a.T @ relative_omega  # R = R_b^T R_a moves as dR/dt = R [body_rate]
    jlog = pin.Jlog3(rel)
    theta = pin.log3(rel)
    theta_rate = jlog @ body_rate
    rotating_frame = -rotation_a.T @ np.cross(omega_a, relative_omega)
    return (
        jlog_rate(theta, theta_rate) @ body_rate + jlog @ rotating_frame + jlog @ rotation_a.T @ relative_angular_drift
    )


def jlog_rate(theta: np.ndarray, theta_rate: np.ndarray) -> np.ndarray:
    """Time derivative of ``Jlog3`` along ``theta(t)`` (the right Jacobian inverse of SO(3)).

    ``Jlog3(theta) = E + [theta]/2 + c(|theta|) [theta]^2`` with
    ``c(x) = 1/x^2 - (1 + cos x) / (2 x sin x)``.
    """
    angle = float(np.linalg.norm(theta))
    hat, hat_rate = pin.skew(theta), pin.skew(theta_rate)
    if angle < 1e-4:
        coeff = 1.0 / 12.0 + angle**2 / 720.0
        coeff_rate = float(theta @ theta_rate) / 360.0
    else:
        coeff = 1.0 / angle**2 - (1.0 + np.cos(angle)) / (2.0 * angle * np.sin(angle))
        dcoeff = -2.0 / angle**3 + (
            np.sin(angle) * angle * np.sin(angle) + (1.0 + np.cos(angle)) * (np.sin(angle) + angle * np.cos(angle))
        ) / (2.0 * (angle * np.sin(angle)) ** 2)
        coeff_rate = dcoeff * float(theta @ theta_rate) / angle
    return 0.5 * hat_rate + coeff_rate * hat @ hat + coeff * (hat_rate @ hat + hat @ hat_rate)


def _plane(entry: dict, kind: str, where: str) -> str | tuple[float, float, float]:
    if kind != "planar-point":
        return "xy"
    raw = entry.get("plane")
    if isinstance(raw, str) and raw in PLANES:
        return raw
    if isinstance(raw, list):
        return tuple(SceneTables.direction(raw, f"{where}.plane"))  # type: ignore[return-value]
    raise SceneError(f"{where}: 'plane' must be one of {choices(PLANES)} or a normal vector, got {raw!r}")


def parse_closure(kind: str):
    """The scene-table reader of closure kind ``kind``: frames a and b (``world`` by default) with
    offsets [m] and rpy angles [rad]; ``plane`` for ``planar-point``."""

    def parse(entry: dict, tables: SceneTables, name: str, where: str) -> FrameClosure:
        tables.check_keys(entry, CLOSURE_KEYS | ({"plane"} if kind == "planar-point" else set()), where)
        plane = _plane(entry, kind, where)
        return FrameClosure(name, kind, *closure_frames(entry, tables, name, where), plane)

    return parse


CONSTRAINT_KINDS.register("point", parse_closure("point"), summary="3 rows: two frame points coincide (world axes)")
CONSTRAINT_KINDS.register(
    "planar-point", parse_closure("planar-point"), summary="2 rows: two frame points coincide within a plane"
)
CONSTRAINT_KINDS.register("weld", parse_closure("weld"), summary="6 rows: two frames coincide (position and rotation)")
