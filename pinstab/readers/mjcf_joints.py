"""The joints of an MJCF file as MuJoCo reads them, beyond the kinematics Pinocchio's MJCF parser builds:

- limits: ``range`` and ``limited`` (``<compiler autolimits>``, ``<default>`` classes), a hinge's range in the
  file's angle unit, a slide's in metres (the parser also converts a slide's range as an angle and limits a joint
  with ``limited="false"``); an unlimited joint has infinite limits. MuJoCo's limits are soft (``solreflimit``,
  ``solimplimit``: a joint passes its range a little); pinstab's are hard (a note says so, naming the joints);
- ``damping`` [N m s/rad or N s/m], ``stiffness`` [N m/rad or N/m] about ``springref`` (the file's angle unit for
  a hinge): a ``joint-spring`` force element each (:mod:`pinstab.forces.joint_spring`), named ``<joint>/spring``;
  MuJoCo's passive force ``-stiffness (q - springref) - damping qdot``. A ball joint's damping acts on its three
  velocities as MuJoCo's; a ball or free joint's stiffness, and a spring on a joint of a composite joint (a body
  with several joints) are refused, naming the joint;
- ``armature`` [kg m^2 or kg]: the parser writes it into ``model.armature`` (rotor inertia, in the mass matrix);
- ``frictionloss`` [N m or N] (MuJoCo's dry joint friction, a force bounded by it with stick and slip): a
  ``joint-friction`` force element each (:mod:`pinstab.forces.joint_friction`), named ``<joint>/frictionloss``, which
  runs the scene event-driven; MuJoCo's is soft (``solreffriction``, ``solimpfriction``: a sticking joint creeps a
  little; a note says so, naming the joints); on a ball or free joint, or a joint of a composite joint, refused;
- ``springdamper`` (stiffness and damping given by a time constant and a damping ratio, from the joint's inertia
  at qpos0) is refused, naming the joint; ``margin`` and the actuator attributes (``actuatorfrcrange``,
  ``actuatorgravcomp``) are noted as not read.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from .mjcf_bodies import joint_kind
from .mjcf_xml import MjcfDocument

SCALAR_JOINTS = {"hinge": 1, "slide": 1, "ball": 4, "free": 7}  # MJCF joint type -> configuration size
SPRINGDAMPER = "springdamper"  # a stiffness and damping from a time constant and a damping ratio: refused
NOT_READ = ("margin", "actuatorfrcrange", "actuatorfrclimited", "actuatorgravcomp")  # noted when given


@dataclass
class JointReader:
    """Reads the joints of ``document`` into the Pinocchio ``model`` built from it.

    Attributes:
        forces: the ``joint-spring`` scene entries of the joints' damping and springs and the ``joint-friction``
            entries of their frictionloss, in the file's order.
        notes: what was changed or not read, in words.
    """

    document: MjcfDocument
    model: pin.Model
    forces: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def read(self) -> None:
        """Every joint of the file: its limits into the model, its damping and spring into :attr:`forces`.

        Raises:
            SceneError: a springdamper, a spring it cannot hold, a bad range.
        """
        limited: list[str] = []
        not_read: dict[str, list[str]] = {}
        friction: list[str] = []
        for body in self.document.root.iter("body"):
            joints = [j for j in body if j.tag in ("joint", "freejoint")]
            names = [str(j.get("name")) for j in joints]
            if len(joints) > 1:
                self.notes.append(f"body {body.get('name')!r}: its joints {', '.join(names)} are one composite joint")
            offset = 0
            for joint, name in zip(joints, names, strict=True):
                where = f"robot.mjcf joint {name!r}"
                kind = joint_kind(self.document, joint, where)
                index = q_index(self.model, name, names[0], offset)
                offset += SCALAR_JOINTS[kind]
                self._refuse(joint, where)
                if self._friction(joint, name, kind, composite=len(joints) > 1, where=where):
                    friction.append(repr(name))
                for key in NOT_READ:
                    if self.document.attribute(joint, key) is not None:
                        not_read.setdefault(key, []).append(name)
                if self._limits(joint, name, kind, index, where):
                    limited.append(name)
                self._spring(joint, name, kind, composite=len(joints) > 1, where=where)
        if limited:
            self.notes.append(
                f"joints {', '.join(map(repr, limited))}: their ranges are held as hard limits (MuJoCo's are soft, "
                "solreflimit/solimplimit: a joint passes its range a little)"
            )
        if friction:
            self.notes.append(
                f"joints {', '.join(friction)}: their frictionloss is held as hard dry friction, sticking exactly "
                "(MuJoCo's is soft, solreffriction/solimpfriction: a sticking joint creeps a little)"
            )
        self.notes += [f"joint {key} of {', '.join(map(repr, joints))} not read" for key, joints in not_read.items()]

    def _refuse(self, joint: ET.Element, where: str) -> None:
        text = self.document.attribute(joint, SPRINGDAMPER)
        if text is not None and np.any(self.document.numbers(joint, SPRINGDAMPER, 2, where) != 0.0):
            raise SceneError(
                f"{where}: springdamper={text!r} (a stiffness and damping from a time constant and a damping ratio) "
                "is not read: give them as stiffness [N m/rad or N/m] and damping [N m s/rad or N s/m]"
            )

    def _limits(self, joint: ET.Element, name: str, kind: str, index: int | None, where: str) -> bool:
        """Write the joint's limits into the model; whether it is limited."""
        limits = joint_limits(self.document, joint, kind, where)
        if limits is None:
            return False
        if kind == "ball":
            self.notes.append(f"joint {name!r}: the cone limit of a ball joint is not read")
            return False
        if index is None:
            self.notes.append(f"joint {name!r}: not found in Pinocchio's model, its range is not read")
            return False
        self.model.lowerPositionLimit[index], self.model.upperPositionLimit[index] = limits
        return bool(np.isfinite(limits).any())

    def _spring(self, joint: ET.Element, name: str, kind: str, composite: bool, where: str) -> None:
        """The joint's damping and spring as a ``joint-spring`` entry (none when both are zero)."""
        damping = self._number(joint, "damping", where)
        stiffness = self._number(joint, "stiffness", where)
        if damping == 0.0 and stiffness == 0.0:
            return
        if composite:
            raise SceneError(
                f"{where}: a damping or stiffness on a joint of a body with several joints (Pinocchio's composite "
                "joint) is not read: give each joint its own body"
            )
        if stiffness and kind in ("ball", "free"):
            raise SceneError(f"{where}: the stiffness of a {kind} joint is not read (a spring on a 1-DOF joint only)")
        factor = self.document.angle_factor() if kind == "hinge" else 1.0
        entry: dict[str, Any] = {"name": f"{name}/spring", "kind": "joint-spring", "joint": name, "damping": damping}
        if stiffness:
            reference = float(self.document.numbers(joint, "springref", 1, where, [0.0])[0])  # of either sign
            entry |= {"stiffness": stiffness, "reference": reference * factor}
        self.forces.append(entry)

    def _friction(self, joint: ET.Element, name: str, kind: str, composite: bool, where: str) -> bool:
        """The joint's frictionloss as a ``joint-friction`` entry (none when zero); whether it has one.

        Raises:
            SceneError: a frictionloss on a ball or free joint, or on a joint of a composite joint.
        """
        friction = self._number(joint, "frictionloss", where)
        if friction == 0.0:
            return False
        if kind in ("ball", "free") or composite:
            what = f"a {kind} joint" if kind in ("ball", "free") else "a joint of a body with several joints"
            raise SceneError(
                f"{where}: frictionloss={friction:g} on {what} is not read (dry joint friction on a 1-DOF joint of its "
                "own body only); remove it or give the joint its own body"
            )
        self.forces.append(
            {"name": f"{name}/frictionloss", "kind": "joint-friction", "joint": name, "friction": friction}
        )
        return True

    def _number(self, joint: ET.Element, key: str, where: str) -> float:
        """The joint's non-negative number ``key`` (damping, stiffness, frictionloss), 0 when not given.

        Raises:
            SceneError: a negative one (MuJoCo refuses it).
        """
        value = float(self.document.numbers(joint, key, 1, where, [0.0])[0])
        if value < 0.0:
            raise SceneError(f"{where}: {key}={value} is negative (MuJoCo refuses it)")
        return value


def joint_limits(document: MjcfDocument, joint: ET.Element, kind: str, where: str) -> tuple[float, float] | None:
    """The joint's (lower, upper) position limits [rad or m], (-inf, inf) when unlimited, None for a free joint."""
    if kind == "free":
        return None
    declared = limited_range(document, joint, "limited", "range", where)
    if declared is None:
        return -np.inf, np.inf
    factor = document.angle_factor() if kind in ("hinge", "ball") else 1.0
    return declared[0] * factor, declared[1] * factor


def limited_range(
    document: MjcfDocument,
    element: ET.Element,
    flag: str,
    key: str,
    where: str,
    attributes: dict[str, str] | None = None,
) -> tuple[float, float] | None:
    """An element's range ``key`` (in the file's numbers) where its ``flag`` (``true``, ``false`` or ``auto``:
    limited when the range is given and ``<compiler autolimits>`` is on) limits it, else None; read from
    ``attributes`` where given (an actuator's, through MuJoCo's shared actuator default), else from the element's
    attributes through its classes.

    Raises:
        SceneError: a flag of another value, a range that is not two numbers or whose low end is above its high.
    """
    given = document.attributes(element) if attributes is None else attributes
    limited = given.get(flag) or "auto"
    if limited not in ("true", "false", "auto"):
        raise SceneError(f"{where}: {flag}={limited!r} is not one of true, false, auto")
    text = given.get(key)
    if limited == "false" or (limited == "auto" and not (document.autolimits and text is not None)):
        return None
    try:
        lower, upper = (float(x) for x in (text or "").split())
    except ValueError:
        raise SceneError(f"{where}: {key}={text!r} is not 2 numbers") from None
    if not (np.isfinite(lower) and np.isfinite(upper)):
        raise SceneError(f"{where}: {key}={text!r} is not 2 finite numbers")
    if lower > upper:
        raise SceneError(f"{where}: {key} lower {lower} > upper {upper}")
    return lower, upper


def q_index(model: pin.Model, name: str, first: str, offset: int) -> int | None:
    """The configuration index of joint ``name``: its own joint, or its place in the body's composite joint."""
    for joint_name, start in ((name, 0), (f"Composite_{first}", offset)):
        if model.existJointName(joint_name):
            return model.joints[model.getJointId(joint_name)].idx_q + start
    return None
