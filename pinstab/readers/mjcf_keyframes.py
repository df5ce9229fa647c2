"""The start of an MJCF robot: a ``<keyframe>``'s ``<key>`` (``qpos``, ``qvel``), the first one by default, or
MuJoCo's ``qpos0`` (every joint at its ``ref``, at rest) in a file without keyframes.

MuJoCo's coordinates are carried to Pinocchio's: the joints in MuJoCo's order (the bodies depth first, each body's
joints in order), a ball's or free joint's quaternion ``w x y z`` written ``x y z w``, a free joint's linear
velocity (of its body's origin, in the world frame) turned into the body's frame. A key's ``ctrl``, ``act``,
``mpos``, ``mquat`` and a non-zero ``time`` are noted as not read (pinstab starts at t = 0 s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..errors import SceneError, choices
from .mjcf_bodies import joint_kind
from .mjcf_equalities import reference_configuration
from .mjcf_joints import SCALAR_JOINTS
from .mjcf_xml import MjcfDocument

VELOCITIES = {"hinge": 1, "slide": 1, "ball": 3, "free": 6}  # MJCF joint type -> qvel size
NOT_READ = ("act", "mpos", "mquat")


@dataclass(frozen=True)
class Start:
    """A robot's start: ``q`` (nq,) [rad, m] and ``v`` (nv,) [rad/s, m/s] of the model the reader built, what
    it is (``keyframe 'home'`` or ``qpos0``), and the key's controls ``ctrl`` (one per actuator of the file, in
    its order; None: not given, MuJoCo's 0)."""

    q: np.ndarray
    v: np.ndarray
    label: str
    ctrl: np.ndarray | None = None


def read_start(document: MjcfDocument, model: pin.Model, name: str | None, notes: list[str]) -> Start:
    """The start of key ``name`` (None: the file's first key, else ``qpos0``); what it leaves out into ``notes``.

    Raises:
        SceneError: ``name`` is not a key of the file (the keys listed), a key's qpos or qvel of another size than
            MuJoCo's model, a joint of the file Pinocchio's model does not hold as MuJoCo orders them.
    """
    keys = document.root.findall("keyframe/key")
    labels = [key.get("name") or f"key{index}" for index, key in enumerate(keys)]  # an unnamed key: by its index
    reference = reference_configuration(model)
    if name is None and not keys:
        return Start(reference, np.zeros(model.nv), "qpos0")
    if name is not None and name not in labels:
        listed = f"keyframes: {choices(labels)}" if labels else "the file has no <keyframe>"
        raise SceneError(f"robot.keyframe {name!r} is not a key of {document.path}; {listed}")
    label = labels[0] if name is None else name
    key = keys[labels.index(label)]
    where = f"robot.mjcf keyframe {label!r}"
    blocks = _blocks(document, model)
    nq, nv = sum(SCALAR_JOINTS[kind] for kind, _, _ in blocks), sum(VELOCITIES[kind] for kind, _, _ in blocks)
    q, v = reference.copy(), np.zeros(model.nv)
    qpos = _numbers(document, key, "qpos", nq, where)
    qvel = _numbers(document, key, "qvel", nv, where)
    for kind, q_at, v_at in blocks:
        size, rates = SCALAR_JOINTS[kind], VELOCITIES[kind]
        if qpos is not None:
            q[q_at : q_at + size] = _pinocchio_q(kind, qpos[:size])
        if qvel is not None:
            v[v_at : v_at + rates] = _pinocchio_v(kind, qvel[:rates], q[q_at : q_at + size])
        qpos = None if qpos is None else qpos[size:]
        qvel = None if qvel is None else qvel[rates:]
    left = [item for item in NOT_READ if key.get(item) is not None]
    if float(key.get("time", "0") or 0.0) != 0.0:
        left.append("time")
    if left:
        notes.append(f"keyframe {label!r}: {', '.join(left)} not read (the run starts at t = 0 s from qpos, qvel)")
    actuators = [item for section in document.root.findall("actuator") for item in section]
    ctrl = _numbers(document, key, "ctrl", len(actuators), where)
    return Start(q, v, f"keyframe {label!r}", ctrl)


def _blocks(document: MjcfDocument, model: pin.Model) -> list[tuple[str, int, int]]:
    """(type, q index, v index) of every joint of the file in MuJoCo's order, in Pinocchio's model.

    Raises:
        SceneError: a body's joints that are not the next joint of Pinocchio's model (named).
    """
    blocks: list[tuple[str, int, int]] = []
    joint_id = 1 + int(
        model.njoints > 1 and model.names[1] == "root_joint"
    )  # a free flyer the scene added: not MuJoCo's
    for body in document.root.iter("body"):
        joints = [j for j in body if j.tag in ("joint", "freejoint")]
        if not joints:
            continue
        kinds = [joint_kind(document, j, f"robot.mjcf joint {j.get('name')!r}") for j in joints]
        if joint_id >= model.njoints or model.joints[joint_id].nq != sum(SCALAR_JOINTS[k] for k in kinds):
            raise SceneError(
                f"robot.mjcf body {body.get('name')!r}: its joints are not where MuJoCo orders them in Pinocchio's "
                f"model of {document.path}; its keyframes cannot be read"
            )
        joint = model.joints[joint_id]
        q_at, v_at = joint.idx_q, joint.idx_v
        for kind in kinds:
            blocks.append((kind, q_at, v_at))
            q_at, v_at = q_at + SCALAR_JOINTS[kind], v_at + VELOCITIES[kind]
        joint_id += 1
    return blocks


def _numbers(document: MjcfDocument, key, attribute: str, size: int, where: str) -> np.ndarray | None:
    if key.get(attribute) is None:
        return None
    return document.numbers(key, attribute, size, where)


def _pinocchio_q(kind: str, qpos: np.ndarray) -> np.ndarray:
    """A joint's MuJoCo qpos as Pinocchio's q: the quaternion ``w x y z`` as ``x y z w``, normalized."""
    if kind not in ("ball", "free"):
        return qpos
    w, x, y, z = qpos[-4:]
    quaternion = np.array([x, y, z, w])
    norm = np.linalg.norm(quaternion)
    quaternion = np.array([0.0, 0.0, 0.0, 1.0]) if norm == 0.0 else quaternion / norm  # MuJoCo's: unit, or identity
    return np.concatenate([qpos[:-4], quaternion])


def _pinocchio_v(kind: str, qvel: np.ndarray, q: np.ndarray) -> np.ndarray:
    """A joint's MuJoCo qvel as Pinocchio's v at its q: a free joint's linear velocity in its body's frame."""
    if kind != "free":
        return qvel
    rotation = pin.Quaternion(q[6], q[3], q[4], q[5]).matrix()
    return np.concatenate([rotation.T @ qvel[:3], qvel[3:]])
