"""Several copies of one URDF robot in a scene: ``[robot] copies``.

``copies`` is a list of tables, one per copy: ``prefix`` (a non-empty string, unique among the copies)
and the copy's placement, ``xyz`` [m] and ``rpy`` [rad] (roll-pitch-yaw, both optional, zero by
default, units allowed as elsewhere). The robot's URDF (``urdf``, ``name`` or ``urdf_text``) is
rewritten into one document: a root link :data:`ROOT_LINK` and, per copy, every link and joint of the
source with ``prefix`` before its name (``finger_tip_link`` becomes ``finger0_finger_tip_link``), its
root link fixed to :data:`ROOT_LINK` at ``xyz``/``rpy`` by the joint ``<prefix>mount``. The source's
top-level materials are kept once; its other top-level elements (transmissions, gazebo tags) are
dropped. Joint names in ``initial.q``, ``locked_joints`` and frames in closures, contacts and forces
then use the prefixed names. In the model each copy's joints are consecutive and depth-first; the copies
come in the order Pinocchio's URDF reader visits the mount joints (by name). Example (two fingers)::

    [robot]
    name = "finger_edu"
    copies = [
        { prefix = "finger0_", xyz = [-0.1, 0.0, 0.0] },
        { prefix = "finger120_", xyz = [0.05, -0.0866, 0.0], rpy = [0.0, 0.0, "120 deg"] },
    ]
"""

from __future__ import annotations

import copy as copying
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SceneError, repeated
from ..tables import check_keys, vector
from .bounds import check_count, check_nesting

COPY_KEYS = {"prefix", "xyz", "rpy"}
ROOT_LINK = "copies_root"
WHERE = "robot.copies"


@dataclass(frozen=True)
class RobotCopy:
    """One copy of the robot.

    Attributes:
        prefix: put before every link and joint name of the copy.
        xyz: the copy's root link position in :data:`ROOT_LINK` [m].
        rpy: its orientation, roll-pitch-yaw [rad].
    """

    prefix: str
    xyz: np.ndarray
    rpy: np.ndarray


def parse_copies(value: Any) -> list[RobotCopy]:
    """The ``copies`` key: a non-empty list of tables with unique prefixes.

    Raises:
        SceneError: naming the item (``robot.copies[i]...``).
    """
    if not isinstance(value, list) or not value:
        raise SceneError(f"{WHERE} must be a non-empty list of tables {{prefix = ..., xyz = [...], rpy = [...]}}")
    copies: list[RobotCopy] = []
    for index, entry in enumerate(value):
        where = f"{WHERE}[{index}]"
        if not isinstance(entry, dict):
            raise SceneError(f"{where} must be a table {{prefix = ..., xyz = [...], rpy = [...]}}, got {entry!r}")
        check_keys(entry, COPY_KEYS, where)
        prefix = entry.get("prefix")
        if not isinstance(prefix, str) or not prefix or any(c.isspace() for c in prefix):
            raise SceneError(f"{where}.prefix must be a non-empty string without spaces, got {prefix!r}")
        for earlier, other in enumerate(copies):
            if other.prefix == prefix:
                raise SceneError(f"{where}.prefix: {prefix!r} is already the prefix of {WHERE}[{earlier}]")
        xyz = vector(entry.get("xyz", [0.0, 0.0, 0.0]), 3, f"{where}.xyz", "length")
        rpy = vector(entry.get("rpy", [0.0, 0.0, 0.0]), 3, f"{where}.rpy", "angle")
        copies.append(RobotCopy(prefix, xyz, rpy))
    return copies


def _numbers(values: np.ndarray) -> str:
    return " ".join(f"{float(x):.17g}" for x in values)


def _root_link(source: ET.Element) -> str:
    """The source's one link that no joint has as its child."""
    children = {child.get("link") for child in source.iterfind("joint/child")}
    roots = [link.get("name") for link in source.iterfind("link") if link.get("name") not in children]
    if len(roots) != 1:
        raise SceneError(f"{WHERE}: the robot's URDF must have exactly one root link to copy, it has {roots}")
    return str(roots[0])


def _prefixed(element: ET.Element, prefix: str) -> ET.Element:
    """A copy of a ``<link>`` or ``<joint>`` with its name and the link/joint names it refers to prefixed."""
    renamed = copying.deepcopy(element)
    renamed.set("name", prefix + element.get("name", ""))
    for tag, attribute in (("parent", "link"), ("child", "link"), ("mimic", "joint")):
        for reference in renamed.iterfind(tag):
            reference.set(attribute, prefix + reference.get(attribute, ""))
    return renamed


def _mount(copy: RobotCopy, root: str) -> ET.Element:
    """The fixed joint ``<prefix>mount`` from :data:`ROOT_LINK` to the copy's root link."""
    joint = ET.Element("joint", {"name": f"{copy.prefix}mount", "type": "fixed"})
    ET.SubElement(joint, "parent", {"link": ROOT_LINK})
    ET.SubElement(joint, "child", {"link": copy.prefix + root})
    ET.SubElement(joint, "origin", {"xyz": _numbers(copy.xyz), "rpy": _numbers(copy.rpy)})
    return joint


def _check_unique(composed: ET.Element) -> None:
    for tag in ("link", "joint"):
        collide = repeated(element.get("name") for element in composed.iterfind(tag))
        if collide:
            raise SceneError(
                f"{WHERE}: the prefixes make {tag} names collide: {', '.join(collide)}; choose other prefixes"
            )


def compose_copies(urdf_text: str | bytes, copies: list[RobotCopy]) -> str:
    """One URDF document holding every copy of the robot ``urdf_text`` under :data:`ROOT_LINK`.

    Raises:
        SceneError: the URDF is not XML with a ``<robot>`` root and one root link, nested deeper than
            :data:`~.bounds.MAX_XML_NESTING`, copies of more links or joints than :data:`~.bounds.MAX_BODIES`, or
            the prefixed names collide.
    """
    try:
        source = ET.fromstring(urdf_text)
    except ET.ParseError as exc:
        raise SceneError(f"{WHERE}: the robot's URDF is not valid XML: {exc}") from None
    check_nesting(source, f"{WHERE}: the robot's URDF")  # before its elements are copied (recursively)
    # before the copies are made (the composed document's joints are counted by check_links)
    check_count(1 + len(copies) * len(source.findall("link")), f"links in {len(copies)} copies", WHERE)
    if source.tag != "robot":
        raise SceneError(f"{WHERE}: the robot's URDF has <{source.tag}> at its root, not <robot>")
    root = _root_link(source)
    composed = ET.Element("robot", {"name": f"{source.get('name', 'robot')}_copies"})
    ET.SubElement(composed, "link", {"name": ROOT_LINK})
    composed.extend(copying.deepcopy(material) for material in source.iterfind("material"))
    for item in copies:
        composed.extend(_prefixed(element, item.prefix) for element in source if element.tag in ("link", "joint"))
        composed.append(_mount(item, root))
    _check_unique(composed)
    return ET.tostring(composed, encoding="unicode")
