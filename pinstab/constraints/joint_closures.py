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
from ..tables import SceneTables, closure_frames
from .base import CONSTRAINT_KINDS
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
            self.force_frame = "world axes (force on a) + the two log3(R_b^T R_a) axes across the hinge (moment on a)"
        else:
            self.force_frame = "frame b axes across the slide (force on a) + log3(R_b^T R_a) axes (moment on a)"

    def _block_form(self) -> tuple[int, np.ndarray]:
        return (2 if self.kind == "revolute" else 3), self.across


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
