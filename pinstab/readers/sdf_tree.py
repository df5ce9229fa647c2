"""The spanning tree of an SDF model and the Pinocchio model built on it.

Joints are taken in document order: a joint whose child has no parent yet (and is not the root, and closes
no cycle) is a tree joint; every other joint, and every ``gearbox``, closes a loop. The model's joints come
depth-first from the root, children in document order. Each Pinocchio joint sits at its SDF joint's frame; a
link's BODY frame (named after it) is at the link's SDF pose, so a configuration of zeros places every link
as the SDF does; ``revolute`` and
``prismatic`` joints become Pinocchio revolute/prismatic joints about their axis, ``ball`` a spherical
joint, ``continuous`` a revolute joint without limits, ``fixed`` merges the child into its parent body.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from .bounds import tree_depth
from .inertia import rotated
from .sdf_document import WORLD_LINK, SdfJoint, SdfModel

ROOT_JOINT = "root_joint"  # the free flyer's name, as Pinocchio's URDF reader calls it
AXIS_ALIGNED = 1e-12


@dataclass
class SdfTree:
    """The spanning tree: the root link, tree joints by child link, loop joints, and each link's joint frame
    (its tree joint's frame; the root's: its SDF pose), in the model frame."""

    root: str
    parent_joint: dict[str, SdfJoint] = field(default_factory=dict)
    loops: list[SdfJoint] = field(default_factory=list)
    frames: dict[str, pin.SE3] = field(default_factory=dict)

    def children(self, joints: list[SdfJoint]) -> dict[str, list[SdfJoint]]:
        """The tree joints (of ``joints``) by parent link, in document order."""
        children: dict[str, list[SdfJoint]] = {}
        for joint in joints:
            if self.parent_joint.get(joint.child) is joint:
                children.setdefault(joint.parent, []).append(joint)
        return children

    def depth(self) -> int:
        """The joints on the longest path from the root (the world, or the root link) down."""
        return tree_depth({child: joint.parent for child, joint in self.parent_joint.items()})


def _top(up: dict[str, str], link: str) -> str:
    """The topmost link above ``link`` in the tree so far (``up``: a link above each link; shortened on the way,
    so that the joints are placed in time about linear in their number)."""
    path = []
    while link in up:
        path.append(link)
        link = up[link]
    for item in path:
        up[item] = link
    return link


def spanning_tree(sdf: SdfModel) -> SdfTree:
    """The tree of ``sdf`` (see the module docstring).

    Raises:
        SceneError: a link that no tree joint reaches from the root (named).
    """
    children = {joint.child for joint in sdf.joints}
    if any(joint.parent == WORLD_LINK for joint in sdf.joints):
        root = WORLD_LINK
    else:
        root = next((name for name in sdf.links if name not in children), next(iter(sdf.links)))
    tree = SdfTree(root)
    up: dict[str, str] = {}
    for joint in sdf.joints:
        child = joint.child
        if joint.type == "gearbox" or child == root or child in tree.parent_joint:
            tree.loops.append(joint)
        elif _top(up, joint.parent) == child:  # the child (without a parent yet) is above the parent: a cycle
            tree.loops.append(joint)
        else:
            tree.parent_joint[child] = joint
            up[child] = joint.parent
    for name, link in sdf.links.items():
        tree.frames[name] = tree.parent_joint[name].placement if name in tree.parent_joint else link.pose
    tree.frames[WORLD_LINK] = pin.SE3.Identity()
    unreached = [name for name in sdf.links if _top(up, name) != root]
    if unreached:
        raise SceneError(
            f"sdf model {sdf.name!r}: links {', '.join(unreached)} are not connected to the root link {root!r}"
        )
    return tree


def _joint_model(joint: SdfJoint, frame: pin.SE3) -> pin.JointModel:
    if joint.type == "ball":
        return pin.JointModelSpherical()
    axis = frame.rotation.T @ joint.axis
    prismatic = joint.type == "prismatic"
    for index, letter in enumerate("XYZ"):
        if abs(axis[index] - 1.0) < AXIS_ALIGNED:
            return getattr(pin, f"JointModel{'P' if prismatic else 'R'}{letter}")()
    return pin.JointModelPrismaticUnaligned(axis) if prismatic else pin.JointModelRevoluteUnaligned(axis)


@dataclass
class _Builder:
    """Adds links depth-first: each link's Pinocchio joint and that joint's frame in the model frame."""

    sdf: SdfModel
    tree: SdfTree
    model: pin.Model = field(default_factory=pin.Model)
    joint_of: dict[str, tuple[int, pin.SE3, int]] = field(default_factory=dict)  # link -> joint, frame, frame id

    def add_body(self, name: str, joint_id: int, joint_frame: pin.SE3, parent_frame: int) -> None:
        """The link's inertia on ``joint_id`` and its BODY frame at the link's SDF pose."""
        link = self.sdf.links[name]
        com = joint_frame.actInv(link.pose * link.inertial_pose)
        inertia = pin.Inertia(link.mass, com.translation, rotated(link.inertia, com.rotation))
        self.model.appendBodyToJoint(joint_id, inertia, pin.SE3.Identity())
        in_joint = joint_frame.actInv(link.pose)
        body = self.model.addFrame(pin.Frame(name, joint_id, parent_frame, in_joint, pin.FrameType.BODY))
        self.joint_of[name] = (joint_id, joint_frame, body)

    def add_subtree(self, name: str) -> None:
        """The links below ``name``, depth-first, children in document order (a stack: no recursion)."""
        children = self.tree.children(self.sdf.joints)
        stack = list(reversed(children.get(name, [])))
        while stack:
            joint = stack.pop()
            self.add_joint(joint)
            stack.extend(reversed(children.get(joint.child, [])))

    def add_joint(self, joint: SdfJoint) -> None:
        """The tree joint ``joint`` (a Pinocchio joint, or a frame when fixed) and its child link's body."""
        parent_joint, parent_frame, parent_body = self.joint_of[joint.parent]
        child_frame = self.tree.frames[joint.child]
        if joint.type == "fixed":
            frame = self.model.addFrame(
                pin.Frame(
                    joint.name,
                    parent_joint,
                    parent_body,
                    parent_frame.actInv(child_frame),
                    pin.FrameType.FIXED_JOINT,
                )
            )
            self.add_body(joint.child, parent_joint, parent_frame, frame)
        else:
            joint_id = self.model.addJoint(
                parent_joint, _joint_model(joint, child_frame), parent_frame.actInv(child_frame), joint.name
            )
            if joint.type in ("revolute", "prismatic"):
                index = self.model.joints[joint_id].idx_q
                if joint.lower is not None:
                    self.model.lowerPositionLimit[index] = joint.lower
                if joint.upper is not None:
                    self.model.upperPositionLimit[index] = joint.upper
            frame = self.model.addJointFrame(joint_id, parent_body)
            self.add_body(joint.child, joint_id, child_frame, frame)


def build_model(sdf: SdfModel, tree: SdfTree, floating: bool) -> pin.Model:
    """The Pinocchio model of the tree: a free flyer ``root_joint`` at the root link's pose when ``floating``."""
    builder = _Builder(sdf, tree)
    builder.model.name = sdf.name
    root = tree.root
    if root == WORLD_LINK:
        if floating:
            raise SceneError(f"sdf model {sdf.name!r} is attached to the world: robot.free_flyer cannot be true")
        builder.joint_of[root] = (0, pin.SE3.Identity(), 0)
    elif floating:
        pose = tree.frames[root]
        joint_id = builder.model.addJoint(0, pin.JointModelFreeFlyer(), pose, ROOT_JOINT)
        builder.add_body(root, joint_id, pose, builder.model.addJointFrame(joint_id, 0))
    else:
        builder.add_body(root, 0, pin.SE3.Identity(), 0)
    builder.add_subtree(root)
    return builder.model


def axis_sign(joint: SdfJoint, axis: np.ndarray, where: str) -> float:
    """+1 or -1: ``axis`` (model frame) along or against ``joint``'s axis; SceneError when not parallel."""
    dot = float(np.dot(axis, joint.axis))
    if abs(abs(dot) - 1.0) > 1e-6:
        raise SceneError(f"{where}: its axis is not parallel to joint {joint.name!r}'s axis")
    return 1.0 if dot > 0 else -1.0
