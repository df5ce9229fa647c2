"""MJCF ``<equality>`` elements as scene tables: ``connect`` and ``weld`` as loop closures (``point``, ``weld``),
``joint`` as joint relations, each with its name.

MuJoCo's definitions, kept here (pinstab's own reading, not Pinocchio 4.1's parser, which raises on ``body2 =
"world"``, anchors a site it dropped at the origin, ignores ``joint`` equalities and loses the names):

- ``connect``: the point ``anchor`` [m] of ``body1`` (in its frame) and the point of ``body2`` (``world`` when
  omitted) where that anchor lies at the model's reference configuration (``qpos0``: the joints at ``ref``) stay
  together; with ``site1``/``site2`` the two sites' origins stay together.
- ``weld``: ``body2``'s pose in ``body1``'s frame stays at ``relpose`` (position, quaternion w x y z), or, when
  ``relpose`` has a zero quaternion (the default), at its value at the reference configuration; with sites the two
  sites' frames stay together.
- ``joint``: ``y - y0 = a0 + a1 (x - x0) + ... + a4 (x - x0)^4`` with y = ``joint1``, x = ``joint2`` (a constant
  without ``joint2``), y0, x0 their reference positions, a = ``polycoef``: read when linear (a2 = a3 = a4 = 0).

An equality without a name is named by its tag and its index among the equalities of that tag (``connect0``:
the first ``connect``). ``solref``/``solimp``/``torquescale`` (MuJoCo's soft constraints) are not used: the rows
hold exactly, their drift corrected by the run's ``--method``; a note says so.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import SceneError, choices
from ..memory import new_data
from ..tables import WORLD
from .mjcf_xml import MjcfDocument

EQUALITY_KINDS = ("connect", "weld", "joint")
SOFT_KEYS = ("solref", "solimp", "torquescale")  # MuJoCo's soft-constraint parameters


@dataclass
class Anchor:
    """One side of a closure: a body frame of the model (or the world) and a pose in it."""

    frame: str
    pose: pin.SE3


@dataclass
class EqualityReader:
    """Reads the equalities of ``document`` against the Pinocchio ``model`` built from it.

    Attributes:
        tables: scene entries by scene array (``closures``), in the file's order.
        notes: what was named, skipped or ignored, in words.
    """

    document: MjcfDocument
    model: pin.Model
    tables: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.data = new_data(self.model)
        self.reference = reference_configuration(self.model)
        pin.framesForwardKinematics(self.model, self.data, self.reference)
        worldbody = self.document.root.find("worldbody")
        self.world_elements = set() if worldbody is None else set(worldbody)
        self.bodies = {b.get("name"): b for b in self.document.root.iter("body") if b.get("name")}
        self.sites = {s.get("name"): s for s in self.document.root.iter("site") if s.get("name")}

    def read(self) -> None:
        """Every equality of the file, into :attr:`tables` and :attr:`notes`."""
        counts: dict[str, int] = {}
        soft: list[str] = []
        for section in self.document.root.findall("equality"):
            for element in section:
                if element.tag is ET.Comment:
                    continue
                index = counts.get(element.tag, 0)
                counts[element.tag] = index + 1
                name = element.get("name") or f"{element.tag}{index}"
                where = f"robot.mjcf equality {name!r} (<{element.tag}>)"
                if element.tag not in EQUALITY_KINDS:
                    raise SceneError(f"{where}: kind not read; MJCF equalities read: {choices(EQUALITY_KINDS)}")
                if not element.get("name"):
                    self.notes.append(f"equality <{element.tag}> number {index} has no name: named {name!r}")
                if self.document.attribute(element, "active") == "false":
                    self.notes.append(f'equality {name!r} is inactive (active="false"): not read')
                    continue
                if any(self.document.attribute(element, key) is not None for key in SOFT_KEYS):
                    soft.append(name)
                entry = {"connect": self._connect, "weld": self._weld, "joint": self._joint}[element.tag]
                self.tables.setdefault("closures", []).append(entry(element, name, where))
        if soft:
            self.notes.append(
                f"solref/solimp/torquescale of equalities {', '.join(map(repr, soft))} ignored (MuJoCo's "
                "soft-constraint parameters): pinstab holds them as rigid constraint rows, their drift corrected by "
                "the run's stabilization method (--method, default baumgarte)"
            )

    # -- the kinds ------------------------------------------------------------------------------
    def _connect(self, element: ET.Element, name: str, where: str) -> dict[str, Any]:
        if element.get("site1") or element.get("site2"):
            a, b = self._site(element, "site1", where), self._site(element, "site2", where)
        else:
            anchor = pin.SE3(np.eye(3), self.document.numbers(element, "anchor", 3, where))
            a = Anchor(self._body(element, "body1", where), anchor)
            b = self._at_reference(a, self._body(element, "body2", where))
        return _closure(name, "point", a, b, where)

    def _weld(self, element: ET.Element, name: str, where: str) -> dict[str, Any]:
        if element.get("site1") or element.get("site2"):
            a, b = self._site(element, "site1", where), self._site(element, "site2", where)
            return _closure(name, "weld", a, b, where)
        body1, body2 = self._body(element, "body1", where), self._body(element, "body2", where)
        relpose = self.document.numbers(element, "relpose", 7, where, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        if np.linalg.norm(relpose[3:]) == 0.0:  # MuJoCo's default: the pose at the reference configuration
            pose = self._world_placement(body1).actInv(self._world_placement(body2))
        else:
            w, x, y, z = relpose[3:]
            pose = pin.SE3(pin.Quaternion(w, x, y, z).normalized().matrix(), relpose[:3])
        return _closure(name, "weld", Anchor(body1, pose), Anchor(body2, pin.SE3.Identity()), where)  # body2 in body1

    def _joint(self, element: ET.Element, name: str, where: str) -> dict[str, Any]:
        coefficients = self.document.numbers(element, "polycoef", 5, where, [0.0, 1.0, 0.0, 0.0, 0.0])
        if np.any(coefficients[2:] != 0.0):
            raise SceneError(
                f"{where}: polycoef {coefficients.tolist()} is of degree {int(np.flatnonzero(coefficients)[-1])}; "
                "pinstab's joint relations are linear: give a2 = a3 = a4 = 0"
            )
        joint1 = self._joint_name(element, "joint1", where)
        y0 = self._reference_position(joint1)
        joints = {joint1: 1.0}
        value = y0 + coefficients[0]
        if element.get("joint2"):
            joint2 = self._joint_name(element, "joint2", where)
            if joint2 == joint1:
                raise SceneError(f"{where}: joint1 and joint2 are the same joint {joint1!r}")
            joints[joint2] = -float(coefficients[1])
            value -= coefficients[1] * self._reference_position(joint2)
        return {"name": name, "kind": "joint-relation", "joints": joints, "value": float(value)}

    # -- names ------------------------------------------------------------------------------------
    def _body(self, element: ET.Element, key: str, where: str) -> str:
        """The body frame ``element[key]`` names (``world`` when ``body2`` is omitted)."""
        body = element.get(key)
        if body is None and key == "body2":
            return WORLD
        if body is None:
            raise SceneError(f"{where}: {key} is required (or site1 and site2)")
        if body == WORLD:
            return WORLD
        if body not in self.bodies:
            raise SceneError(f"{where}: {key} {body!r} is not a body of the file; bodies: {choices(self.bodies)}")
        if not self.model.existFrame(body, pin.FrameType.BODY):
            raise SceneError(f"{where}: {key} {body!r} is not in the model Pinocchio's MJCF parser built from the file")
        return body

    def _site(self, element: ET.Element, key: str, where: str) -> Anchor:
        """The body frame holding site ``element[key]`` and the site's pose in it."""
        site = element.get(key)
        if site is None:
            raise SceneError(f"{where}: site1 and site2 go together; {key} is missing")
        if site not in self.sites:
            raise SceneError(f"{where}: {key} {site!r} is not a site of the file; sites: {choices(self.sites)}")
        if self.sites[site] in self.world_elements:  # Pinocchio's parser drops the sites of <worldbody>
            return Anchor(WORLD, self.document.pose(self.sites[site], f"{where}: site {site!r}"))
        if not self.model.existFrame(site, pin.FrameType.OP_FRAME):
            raise SceneError(f"{where}: {key} {site!r} is not in the model Pinocchio's MJCF parser built from the file")
        frame = self.model.frames[self.model.getFrameId(site, pin.FrameType.OP_FRAME)]
        body = self.document.parents[self.sites[site]].get("name")
        if body is None or not self.model.existFrame(body, pin.FrameType.BODY):
            raise SceneError(f"{where}: {key} {site!r} is on a body without a name; name it to use the site")
        body_frame = self.model.frames[self.model.getFrameId(body, pin.FrameType.BODY)]
        return Anchor(body, body_frame.placement.actInv(frame.placement))

    def _joint_name(self, element: ET.Element, key: str, where: str) -> str:
        joint = element.get(key)
        names = [n for n in self.model.names if n != "universe"]
        if joint is None or not self.model.existJointName(joint) or joint == "universe":
            raise SceneError(f"{where}: {key} {joint!r} is not a joint of the model; joints: {choices(names)}")
        return joint

    # -- the reference configuration --------------------------------------------------------------
    def _world_placement(self, frame: str) -> pin.SE3:
        if frame == WORLD:
            return pin.SE3.Identity()
        return self.data.oMf[self.model.getFrameId(frame, pin.FrameType.BODY)]

    def _at_reference(self, a: Anchor, body: str) -> Anchor:
        """The pose in ``body`` that coincides with ``a`` at the reference configuration."""
        return Anchor(body, self._world_placement(body).actInv(self._world_placement(a.frame) * a.pose))

    def _reference_position(self, joint: str) -> float:
        index = self.model.joints[self.model.getJointId(joint)].idx_q
        return float(self.reference[index])


def reference_configuration(model: pin.Model) -> np.ndarray:
    """MuJoCo's ``qpos0`` as Pinocchio's parser stored it (the joints at ``ref``), else the neutral configuration."""
    if "qpos0" in model.referenceConfigurations:
        q = np.array(model.referenceConfigurations["qpos0"])
        if q.shape == (model.nq,):
            return q
    return pin.neutral(model)


def _closure(name: str, kind: str, a: Anchor, b: Anchor, where: str) -> dict[str, Any]:
    """The scene table of a closure between ``a`` and ``b`` (a side in the world goes second)."""
    if a.frame == WORLD:
        a, b = b, a
    if a.frame == WORLD:
        raise SceneError(f"{where}: both sides are the world; one must be a body")
    entry: dict[str, Any] = {"name": name, "kind": kind, "frame_a": a.frame, "frame_b": b.frame}
    for side, anchor in (("a", a), ("b", b)):
        entry[f"offset_{side}"] = anchor.pose.translation.tolist()
        if kind == "weld":
            entry[f"rpy_{side}"] = pin.rpy.matrixToRpy(anchor.pose.rotation).tolist()
    return entry
