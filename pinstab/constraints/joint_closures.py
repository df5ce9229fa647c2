"""Loop closures that leave one joint axis free: kinds ``revolute`` and ``prismatic`` (5 rows each).

Frames ``a`` and ``b`` coincide at assembly; ``axis`` is a direction in their axes (the same at assembly).

- ``revolute``: the points coincide (3 rows, world axes) and the relative rotation ``log3(R_b^T R_a)`` has
  no component across the axis (2 rows): frame a may only turn about the axis (|angle| < pi).
- ``prismatic``: the relative rotation is zero (3 rows) and ``R_b^T (p_a - p_b)`` has no component across
  the axis (2 rows, frame b axes): frame a may only slide along the axis.

Multipliers: the rows' forces [N] and moments [N m] on body a, in the rows' axes.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from ..kinematics import Kinematics, relative_offset
from ..tables import SceneTables, closure_frames
from .base import CONSTRAINT_KINDS, VelocityTerms
from .loops import CLOSURE_KEYS, FrameClosure, plane_basis

JOINT_CLOSURE_KEYS = CLOSURE_KEYS | {"axis"}


class JointClosure(FrameClosure):
    """A ``revolute`` or ``prismatic`` closure between frame a and frame b (None: the world placement).

    Args:
        kind: ``revolute`` or ``prismatic``. axis: the free direction in frame a's (= b's) axes [-].
    """

    def __init__(
        self, name: str, kind: str, frame_a: int, frame_b: int | None, world_placement_b: pin.SE3 | None, axis
    ) -> None:
        super().__init__(name, "weld", frame_a, frame_b, world_placement_b)
        self.kind, self.rows = kind, 5
        self.across = plane_basis(np.asarray(axis, float))  # 2 x 3, orthonormal, normal to the axis
        if kind == "revolute":
            self.selection_rows = np.zeros((5, 6))
            self.selection_rows[:3, :3] = np.eye(3)
            self.selection_rows[3:, 3:] = self.across
            self.force_frame = "world axes (force on a) + the two log3(R_b^T R_a) axes across the hinge (moment on a)"
        else:
            self.force_frame = "frame b axes across the slide (force on a) + log3(R_b^T R_a) axes (moment on a)"

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        weld = super().residual(kin, q, t)
        if self.kind == "revolute":
            return self.selection_rows @ weld
        return np.concatenate([self.across @ self._placement_b(kin).rotation.T @ weld[:3], weld[3:]])

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        weld = super().velocity_terms(kin, q, t).jacobian
        if self.kind == "revolute":
            return VelocityTerms(self.selection_rows @ weld, np.zeros(5))
        _, slide = relative_offset(kin, self.frame_a, self.frame_b, self.world_placement_b)
        linear = self.across @ slide
        return VelocityTerms(np.vstack([linear, weld[3:]]), np.zeros(5))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        weld = super().drift(kin, q, v, t)
        if self.kind == "revolute":
            return self.selection_rows @ weld
        rotation_b = self._placement_b(kin).rotation
        gap = kin.placement(self.frame_a).translation - self._placement_b(kin).translation
        gap_rate = kin.velocity(self.frame_a).linear.copy()
        omega_b, alpha_b = np.zeros(3), np.zeros(3)
        if self.frame_b is not None:
            gap_rate -= kin.velocity(self.frame_b).linear
            omega_b = kin.velocity(self.frame_b).angular
            alpha_b = kin.drift_acceleration(self.frame_b).angular
        second = weld[:3] - np.cross(alpha_b, gap) - 2.0 * np.cross(omega_b, gap_rate)
        second += np.cross(omega_b, np.cross(omega_b, gap))
        return np.concatenate([self.across @ rotation_b.T @ second, weld[3:]])


def parse_joint_closure(kind: str):
    """The scene-table reader of ``revolute``/``prismatic``: frames a and b (``world`` by default) with
    offsets [m] and rpy angles [rad], and ``axis`` (required, in the frames' axes)."""

    def parse(entry: dict, tables: SceneTables, name: str, where: str) -> JointClosure:
        tables.check_keys(entry, JOINT_CLOSURE_KEYS, where)
        if "axis" not in entry:
            raise SceneError(f"{where}: 'axis' (the free direction, in the frames' axes) is required")
        axis = tables.direction(entry["axis"], f"{where}.axis")
        return JointClosure(name, kind, *closure_frames(entry, tables, name, where), axis)

    return parse


CONSTRAINT_KINDS.register(
    "revolute", parse_joint_closure("revolute"), summary="5 rows: two frames coincide but for a turn about 'axis'"
)
CONSTRAINT_KINDS.register(
    "prismatic", parse_joint_closure("prismatic"), summary="5 rows: two frames coincide but for a slide along 'axis'"
)
