"""``joint-friction``: dry (Coulomb) friction on a 1-DOF joint, a torque [N m] or force [N] bounded by ``friction``.

The joint sticks (its velocity held at zero) while the torque that needs stays within the bound, and slips
otherwise, the friction then ``-friction sign(qdot)``. Its torque is no function of the state: it is the event-driven
contacts' (:mod:`pinstab.integration.events`), which hold a sticking joint as a one-row bilateral entry (its row
``e_i``, as a held joint limit's; its reaction the friction torque, bounded) and a slipping one's friction as an applied
torque of the slip's sign, switched at located events: a slip stopping (its velocity reaching zero) or a stick breaking
(the torque it needs reaching the bound); the modes of the joints at rest are chosen by
:mod:`pinstab.solvers.joint_friction_modes`. Any other path refuses a scene with joint friction, naming the joint.
MJCF's ``frictionloss`` is read as one (:mod:`pinstab.readers.mjcf_joints`).
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np

from ..errors import PinstabError, SceneError
from ..kernels import RowBlock
from ..kinematics import Kinematics
from ..tables import SceneTables
from .base import FORCE_KINDS, ForceElement, bounded_load

FRICTION_KEYS = {"name", "kind", "joint", "friction"}
EVENT_MODE = "event-driven contacts (contacts='event', --contacts event)"  # the one path that takes joint friction


class JointFriction(ForceElement):
    """Dry friction on one 1-DOF joint (see the module).

    Args:
        name: element name. joint: the joint's name. friction: the bound [N m or N], > 0. index_q, index_v: the
            joint's configuration and velocity index.
    """

    needs_kinematics = False

    def __init__(self, name: str, joint: str, friction: float, index_q: int, index_v: int) -> None:
        self.name, self.joint, self.friction, self.index_q, self.index_v = name, joint, friction, index_q, index_v

    @cached_property
    def row(self) -> RowBlock:
        """The sticking row in the compiled core: a joint-limit row (kind 8, Jacobian ``e_i``, no drift) whose
        acceleration row ``a_i = 0`` holds the joint's velocity; its multiplier is the friction torque [N m or N]."""
        indices = np.array([self.index_q], np.int32), np.array([self.index_v], np.int32)
        block = RowBlock(8, -1, -1, np.eye(4), np.zeros((0, 3)), np.array([1.0]), *indices)
        block.bound = 0.0
        return block

    def __getstate__(self) -> dict[str, Any]:
        """The fields without the compiled row (not picklable: built again at first use)."""
        return {key: value for key, value in self.__dict__.items() if key != "row"}

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        """Refused: the friction of a sticking joint is no function of the state (see the module).

        Raises:
            PinstabError: naming the joint and the path that takes it.
        """
        raise refusal([self], "this path")

    def power(self, kin: Kinematics, v: np.ndarray, t: float) -> float:
        """The friction's power [W]: ``-friction |qdot|`` (zero while it sticks)."""
        return -self.friction * abs(float(v[self.index_v]))


def joint_frictions(forces: list[ForceElement]) -> list[JointFriction]:
    """The joint frictions among a scene's force elements."""
    return [element for element in forces if isinstance(element, JointFriction)]


def refusal(frictions: list[JointFriction], mode: str) -> PinstabError:
    """The error of a ``mode`` that cannot take the joint frictions ``frictions``, naming them and the mode to use."""
    named = ", ".join(f"{f.name} (joint {f.joint})" for f in frictions)
    return PinstabError(
        f"joint friction {named}: {mode} cannot take dry joint friction (stick and slip); run it with {EVENT_MODE}"
    )


@FORCE_KINDS.register("joint-friction", summary="dry friction on a 1-DOF joint, bounded by 'friction', stick and slip")
def parse_joint_friction(entry: dict, tables: SceneTables, name: str, where: str) -> JointFriction:
    """Scene table: ``joint`` (a 1-DOF joint) and ``friction`` [N m or N], > 0 and at most 1e6."""
    tables.check_keys(entry, FRICTION_KEYS, where)
    model = tables.model
    joint = model.joints[tables.joint_id(entry.get("joint"), f"{where}.joint")]
    if joint.nv != 1 or joint.nq != 1:
        raise SceneError(
            f"{where}: joint {entry['joint']!r} has {joint.nq} coordinates and {joint.nv} DOF; joint friction needs a "
            "1-DOF joint (revolute or prismatic)"
        )
    friction = tables.number(entry, "friction", where)
    if not friction > 0.0:
        raise SceneError(f"{where}.friction must be > 0 [N m or N], got {friction}")
    bounded_load(np.array([friction]), f"{where}.friction", "N m or N")
    return JointFriction(name, str(entry["joint"]), friction, joint.idx_q, joint.idx_v)
