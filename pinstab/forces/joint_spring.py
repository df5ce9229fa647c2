"""``joint-spring``: a spring-damper on a joint coordinate, or on the free axis of a loop closure.

On a 1-DOF joint (``joint``): torque [N m] or force [N] ``-k (q - q_ref) - c qdot``; on a multi-DOF joint
(a ball) only damping, ``-c v`` on each of its velocity coordinates. On a list of 1-DOF joints (``joints``, a
posture held by PD): one such spring-damper per joint, named ``<name>/<joint>``, with the same gains, each held at
``reference``: a value, ``"start"`` (its position in the scene's initial configuration) or a table by joint.
Between two frames (``frame_a``, ``frame_b`` with offsets and rpy, as a closure's, ``axis`` in their axes and
``motion`` ``revolute`` or ``prismatic``): the same law on the free coordinate s, the turn
``axis . log3(R_b^T R_a)`` [rad] or the slide ``axis . R_b^T (p_a - p_b)`` [m], applied as
``-(k (s - s_ref) + c sdot) ds/dq``.
Stored energy ``k (s - s_ref)^2 / 2`` [J].
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import SceneError, choices, repeated
from ..kernels import RowBlock, block_jacobian, block_residual, joint_spring_force
from ..kinematics import Kinematics
from ..tables import SceneTables, closure_frames
from ..units import within_ceiling
from .base import FORCE_KINDS, ForceElement

SPRING_KEYS = {"name", "kind", "stiffness", "reference", "damping"}
JOINT_KEYS = SPRING_KEYS | {"joint"}
POSTURE_KEYS = SPRING_KEYS | {"joints"}
START = "start"  # the list form's reference: each joint's position in the scene's initial configuration
FRAME_KEYS = SPRING_KEYS | {"frame_a", "offset_a", "rpy_a", "frame_b", "offset_b", "rpy_b", "axis", "motion"}
MOTIONS = ("revolute", "prismatic")
PRISMATIC = 3  # the compiled row kind (cpp/core_rows.hpp RowKind::prismatic): its rows R_b^T (p_a - p_b) across,
# then log3(R_b^T R_a)


class JointSpring(ForceElement):
    """``-k (s - s_ref) - c sdot`` along a joint coordinate or a closure's free axis.

    Args:
        name: element name. stiffness: k [N m/rad or N/m]. reference: s_ref [rad or m]. damping: c [N m s/rad
            or N s/m]. dofs: the joint's velocity indices (joint form), or None (frame form).
        q_index: the 1-DOF joint's configuration index. frames: (frame a, frame b or None, world placement of
            b, axis, motion) of the frame form.
    """

    def __init__(
        self,
        name: str,
        stiffness: float,
        reference: float,
        damping: float,
        dofs: np.ndarray | None = None,
        q_index: int | None = None,
        frames: tuple | None = None,
    ) -> None:
        self.name, self.stiffness, self.reference, self.damping = name, stiffness, reference, damping
        self.dofs, self.q_index, self.frames = dofs, q_index, frames  # reads kin.q: needs the kinematics pass
        self._form = self.compiled_form({})  # the joint form's force is the core's (cpp/core_kernel.cpp)
        self._rows = None if frames is None else self._frame_rows(*frames)

    @staticmethod
    def _frame_rows(frame_a: int, frame_b: int | None, placement_b: pin.SE3, axis: np.ndarray, motion: str) -> tuple:
        """The frame form's coordinate as compiled rows (``cpp/core_rows.cpp``): a prismatic block whose first slide
        row is along ``axis`` (its second, zero, unused), and the projection (on its rows) that gives s: the slide
        ``axis . R_b^T (p_a - p_b)`` [m] (row 0) or the turn ``axis . log3(R_b^T R_a)`` [rad] (rows 2-4)."""
        selection = np.vstack([axis, np.zeros(3)])
        block_b = -1 if frame_b is None else frame_b
        block = RowBlock(PRISMATIC, frame_a, block_b, placement_b.homogeneous, selection)
        projection = np.zeros(5)
        if motion == "prismatic":
            projection[0] = 1.0
        else:
            projection[2:] = axis
        return block, projection

    def coordinate(self, kin: Kinematics) -> tuple[float, np.ndarray]:
        """The 1-DOF coordinate s [rad or m] and its gradient ds/dq (nv,)."""
        if self.frames is None:
            gradient = np.zeros(kin.model.nv)
            gradient[self.dofs] = 1.0
            return float(kin.q[self.q_index]), gradient
        block, projection = self._rows
        value = block_residual(kin.model, kin.data, block, kin.q, 0.0)
        jacobian = block_jacobian(kin.model, kin.data, block, 0.0)[0]
        return float(projection @ value), projection @ jacobian

    def compiled_form(self, rows: Mapping[str, slice]) -> dict[str, Any] | None:
        """The joint form as the core kernel takes it (``cpp/core_kernel.hpp`` JointSpringSpec); None for the frame
        form."""
        if self.frames is not None:
            return None
        return {
            "kind": "joint-spring",
            "dofs": np.asarray(self.dofs, dtype=np.int32),
            "q_index": -1 if self.q_index is None else int(self.q_index),
            "stiffness": float(self.stiffness),
            "reference": float(self.reference),
            "damping": float(self.damping),
        }

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        if self._form is not None:  # the joint form: the core kernel's add_joint_springs
            return joint_spring_force(self._form, kin.q, v)
        value, gradient = self.coordinate(kin)
        return -(self.stiffness * (value - self.reference) + self.damping * float(gradient @ v)) * gradient

    def power(self, kin: Kinematics, v: np.ndarray, t: float) -> float:
        if self.q_index is None and self.frames is None:
            return -self.damping * float(v[self.dofs] @ v[self.dofs])
        _, gradient = self.coordinate(kin)
        return -self.damping * float(gradient @ v) ** 2

    @property
    def stores_energy(self) -> bool:
        return bool(self.stiffness)

    def potential_energy(self, kin: Kinematics) -> float:
        if not self.stiffness:
            return 0.0
        value, _ = self.coordinate(kin)
        return 0.5 * self.stiffness * (value - self.reference) ** 2


def _frames(entry: dict, tables: SceneTables, name: str, where: str) -> tuple:
    motion = entry.get("motion")
    if motion not in MOTIONS:
        raise SceneError(f"{where}.motion must be one of {choices(MOTIONS)}, got {motion!r}")
    axis = tables.direction(entry.get("axis"), f"{where}.axis")
    frame_a, frame_b, placement_b = closure_frames(entry, tables, name, where)
    placement_b = pin.SE3.Identity() if placement_b is None else placement_b  # (read only on the world side)
    return frame_a, frame_b, placement_b, axis, motion


@FORCE_KINDS.register(
    "joint-spring", summary="a spring-damper on a joint coordinate, a list of them, or a closure's free axis"
)
def parse_joint_spring(entry: dict, tables: SceneTables, name: str, where: str) -> JointSpring | list[JointSpring]:
    """Scene table: ``joint``, ``joints`` (a list of 1-DOF joints: one spring each, ``<name>/<joint>``; ``reference``
    ``"start"`` holds each at its initial position) or the frame form (see the module), ``stiffness`` [N m/rad or
    N/m], ``reference`` [rad or m], ``damping`` [N m s/rad or N s/m]."""
    form = "joints" if "joints" in entry else "joint" if "joint" in entry else "frame"
    tables.check_keys(entry, {"joints": POSTURE_KEYS, "joint": JOINT_KEYS, "frame": FRAME_KEYS}[form], where)
    stiffness = tables.number(entry, "stiffness", where, 0.0)
    damping = tables.number(entry, "damping", where, 0.0)
    for label, value in (("stiffness", stiffness), ("damping", damping)):
        if value < 0:
            raise SceneError(f"{where}.{label} must be >= 0, got {value}")
    within_ceiling(stiffness, f"{where}.stiffness", "N m/rad or N/m")
    within_ceiling(damping, f"{where}.damping", "N m s/rad or N s/m")
    if form == "joints":
        return _posture(entry, tables, name, where, stiffness, damping)
    reference = tables.quantity(entry.get("reference", 0.0), "coordinate", f"{where}.reference")
    if form == "frame":
        return JointSpring(name, stiffness, reference, damping, frames=_frames(entry, tables, name, where))
    joint = tables.model.joints[tables.joint_id(entry["joint"], f"{where}.joint")]
    dofs = np.arange(joint.idx_v, joint.idx_v + joint.nv)
    if joint.nv == 1 and joint.nq == 1:
        return JointSpring(name, stiffness, reference, damping, dofs, q_index=joint.idx_q)
    if stiffness:
        raise SceneError(f"{where}: joint {entry['joint']!r} has {joint.nv} DOF; a stiffness needs a 1-DOF joint")
    return JointSpring(name, 0.0, 0.0, damping, dofs)


def _posture(
    entry: dict, tables: SceneTables, name: str, where: str, stiffness: float, damping: float
) -> list[JointSpring]:
    """The list form: one joint spring per joint of ``joints`` (1-DOF, each once), at ``reference`` [rad or m]: a
    value for all, ``"start"`` (each at its position in the scene's initial configuration) or a table by joint (of
    values or ``"start"``; a joint it leaves out is held at its start)."""
    joints = entry["joints"]
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) for j in joints):
        raise SceneError(f"{where}.joints must be a non-empty list of joint names, got {joints!r}")
    twice = repeated(joints)
    if twice:
        raise SceneError(f"{where}.joints names {', '.join(twice)} more than once")
    value = entry.get("reference", 0.0)
    if isinstance(value, dict):
        tables.check_keys(value, set(joints), f"{where}.reference")
    elif isinstance(value, str) and value != START and len(value.split()) != 2:
        raise SceneError(
            f"{where}.reference must be a number, '<number> <unit>', {START!r} or a table by joint, got {value!r}"
        )
    springs = []
    for joint_name in joints:
        joint = tables.model.joints[tables.joint_id(joint_name, f"{where}.joints")]
        if joint.nv != 1 or joint.nq != 1:
            raise SceneError(
                f"{where}.joints: joint {joint_name!r} has {joint.nq} coordinates; the list form takes 1-DOF joints"
            )
        held = value.get(joint_name, START) if isinstance(value, dict) else value
        if held == START:
            held = float(tables.q0[joint.idx_q])
        else:
            held = tables.quantity(held, "coordinate", f"{where}.reference.{joint_name}")
        springs.append(
            JointSpring(f"{name}/{joint_name}", stiffness, held, damping, np.array([joint.idx_v]), joint.idx_q)
        )
    return springs
