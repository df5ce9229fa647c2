"""An SDF document read with the standard library's XML parser: one ``<model>`` (at the root or in one
``<world>``), its links and joints with every pose expressed in the model frame.

SDF 1.6 conventions: a link's ``<pose>`` is in the model frame, a joint's in its child link's frame, an
inertial's or a visual's in its link's frame; a joint axis is in the joint frame unless
``<use_parent_model_frame>`` is 1 (1.6) or its ``<xyz expressed_in="__model__">`` (1.7+). A pose with a
``frame``/``relative_to`` other than the default is refused (named), as are nested models and includes.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import SceneError, choices, repeated
from .bounds import check_count, check_nesting, read_bounded
from .inertia import check_body

JOINT_TYPES = ("revolute", "continuous", "prismatic", "ball", "fixed", "gearbox")
WORLD_LINK = "world"
UNLIMITED = 1e16  # SDF's default limit magnitude: no limit


@dataclass
class SdfVisual:
    """A visual or collision element: its placement in the link frame and its ``<geometry>`` element."""

    name: str
    pose: pin.SE3
    geometry: ET.Element
    rgba: tuple[float, float, float, float] | None = None


@dataclass
class SdfLink:
    """A link: pose in the model frame; mass [kg], inertial pose in the link frame, inertia [kg m^2]."""

    name: str
    pose: pin.SE3
    mass: float = 0.0
    inertial_pose: pin.SE3 = field(default_factory=pin.SE3.Identity)
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    visuals: list[SdfVisual] = field(default_factory=list)
    collisions: list[SdfVisual] = field(default_factory=list)


@dataclass
class SdfJoint:
    """A joint: its frame in the model frame (``placement``), axis and axis2 as unit vectors in the model
    frame, position limits [rad or m] (None: unlimited), ``<dynamics>`` damping [N m s/rad or N s/m],
    friction [N m or N], spring stiffness [N m/rad or N/m] and reference [rad or m]; gearbox data."""

    name: str
    type: str
    parent: str
    child: str
    placement: pin.SE3
    axis: np.ndarray | None = None
    axis2: np.ndarray | None = None
    lower: float | None = None
    upper: float | None = None
    damping: float = 0.0
    friction: float = 0.0
    stiffness: float = 0.0
    reference: float = 0.0
    gearbox_ratio: float = 1.0
    gearbox_reference: str | None = None


@dataclass
class SdfModel:
    """The model: name, links and joints in document order, whether it is ``<static>``."""

    name: str
    links: dict[str, SdfLink]
    joints: list[SdfJoint]
    static: bool = False


def _numbers(text: str | None, count: int, where: str) -> np.ndarray:
    try:
        values = np.array([float(x) for x in (text or "").split()])
    except ValueError:
        values = np.zeros(0)
    if values.shape != (count,) or not np.isfinite(values).all():
        raise SceneError(f"{where}: {text!r} is not {count} finite numbers")
    return values


def _number(element: ET.Element | None, tag: str, default: float, where: str) -> float:
    text = None if element is None else element.findtext(tag)
    if text is None:
        return default
    return float(_numbers(text, 1, f"{where} <{tag}>")[0])


def _pose(element: ET.Element, where: str) -> pin.SE3:
    pose = element.find("pose")
    if pose is None:
        return pin.SE3.Identity()
    frame = pose.get("relative_to", pose.get("frame", ""))
    if frame:
        raise SceneError(f"{where}: <pose> relative to {frame!r} is not supported; give it in the default frame")
    xyz_rpy = _numbers(pose.text, 6, f"{where} <pose>")
    return pin.SE3(pin.rpy.rpyToMatrix(xyz_rpy[3:]), xyz_rpy[:3])


def _visuals(link: ET.Element, tag: str, where: str) -> list[SdfVisual]:
    items = []
    for index, element in enumerate(link.findall(tag)):
        name = element.get("name", f"{tag}{index}")
        geometry = element.find("geometry")
        if geometry is None:
            raise SceneError(f"{where} {tag} {name!r}: <geometry> is missing")
        material = element.find("material")
        color = None if material is None else (material.findtext("diffuse") or material.findtext("ambient"))
        rgba = None
        if color is not None:
            values = [float(x) for x in _numbers(color, len(color.split()), f"{where} {tag} {name!r} color")]
            rgba = (*values[:3], values[3] if len(values) > 3 else 1.0)
        items.append(SdfVisual(name, _pose(element, f"{where} {tag} {name!r}"), geometry, rgba))
    return items


def _link(element: ET.Element, path: Path) -> SdfLink:
    name = element.get("name", "")
    where = f"robot.sdf {path}: sdf link {name!r}"
    link = SdfLink(name, _pose(element, where))
    inertial = element.find("inertial")
    if inertial is not None:
        link.mass = _number(inertial, "mass", 1.0, where)
        link.inertial_pose = _pose(inertial, f"{where} <inertial>")
        moments = inertial.find("inertia")
        i = {key: _number(moments, key, 1.0 if key[1] == key[2] else 0.0, where) for key in _INERTIA_KEYS}
        link.inertia = np.array(
            [[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]], [i["ixz"], i["iyz"], i["izz"]]]
        )
        check_body(link.mass, link.inertia, where, triangle=False)  # SDF robots as published, like example-robot-data's
    link.visuals = _visuals(element, "visual", where)
    link.collisions = _visuals(element, "collision", where)
    return link


_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def _axis(joint: ET.Element, tag: str, frame: pin.SE3, where: str) -> np.ndarray | None:
    axis = joint.find(tag)
    if axis is None:
        return None
    xyz = axis.find("xyz")
    direction = _numbers(None if xyz is None else xyz.text, 3, f"{where} <{tag}><xyz>")
    norm = float(np.linalg.norm(direction))
    if norm < 1e-9:
        raise SceneError(f"{where}: <{tag}> xyz {direction.tolist()} is not a direction")
    in_model = axis.findtext("use_parent_model_frame", "0").strip() in ("1", "true") or (
        xyz is not None and xyz.get("expressed_in") == "__model__"
    )
    return direction / norm if in_model else frame.rotation @ direction / norm


def _joint(element: ET.Element, links: dict[str, SdfLink]) -> SdfJoint:
    name, kind = element.get("name", ""), element.get("type", "")
    where = f"sdf joint {name!r}"
    if kind not in JOINT_TYPES:
        raise SceneError(f"{where}: type {kind!r} is not supported; supported types: {choices(JOINT_TYPES)}")
    ends = {}
    for end in ("parent", "child"):
        link = (element.findtext(end) or "").strip()
        if link not in links and not (end == "parent" and link == WORLD_LINK):
            raise SceneError(f"{where}: {end} link {link!r} does not exist; links: {choices(links)}")
        ends[end] = link
    if ends["child"] == ends["parent"]:
        raise SceneError(f"{where}: parent and child are the same link {ends['child']!r}")
    placement = links[ends["child"]].pose * _pose(element, where)
    joint = SdfJoint(name, kind, ends["parent"], ends["child"], placement)
    joint.axis = _axis(element, "axis", placement, where)
    joint.axis2 = _axis(element, "axis2", placement, where)
    if kind in ("revolute", "prismatic", "continuous", "gearbox") and joint.axis is None:
        raise SceneError(f"{where}: a {kind} joint needs an <axis><xyz>")
    axis = element.find("axis")
    limit = None if axis is None else axis.find("limit")
    if limit is not None and kind in ("revolute", "prismatic"):
        lower, upper = (_number(limit, key, sign * UNLIMITED, where) for key, sign in (("lower", -1), ("upper", 1)))
        if lower > upper:
            raise SceneError(f"{where}: limit lower {lower} > upper {upper}")
        joint.lower = None if lower <= -UNLIMITED else lower
        joint.upper = None if upper >= UNLIMITED else upper
    dynamics = None if axis is None else axis.find("dynamics")
    joint.damping = _number(dynamics, "damping", 0.0, where)
    joint.friction = _number(dynamics, "friction", 0.0, where)
    joint.stiffness = _number(dynamics, "spring_stiffness", 0.0, where)
    joint.reference = _number(dynamics, "spring_reference", 0.0, where)
    for label, value in (("damping", joint.damping), ("spring_stiffness", joint.stiffness)):
        if value < 0:
            raise SceneError(f"{where}: <dynamics><{label}> {value} is negative")
    if kind == "gearbox":
        joint.gearbox_ratio = _number(element, "gearbox_ratio", 1.0, where)
        joint.gearbox_reference = (element.findtext("gearbox_reference_body") or "").strip()
        if joint.gearbox_reference not in links:
            raise SceneError(
                f"{where}: gearbox_reference_body {joint.gearbox_reference!r} does not exist; links: {choices(links)}"
            )
        if joint.axis2 is None:
            raise SceneError(f"{where}: a gearbox joint needs an <axis2><xyz>")
    return joint


def _model_element(root: ET.Element, path: Path) -> ET.Element:
    if root.tag != "sdf":
        raise SceneError(f"robot.sdf {path}: the root element is <{root.tag}>, not <sdf>")
    models = root.findall("model") + root.findall("world/model")
    if len(models) != 1:
        raise SceneError(f"robot.sdf {path}: expected exactly one <model>, found {len(models)}")
    model = models[0]
    for tag in ("model", "include"):
        if model.find(tag) is not None:
            raise SceneError(f"robot.sdf {path}: nested <{tag}> in model {model.get('name')!r} is not supported")
    return model


def read_document(path: Path) -> SdfModel:
    """The one model of the SDF file ``path``.

    Raises:
        SceneError: the file is missing, not XML or beyond a bound of :mod:`.bounds`, not an ``<sdf>`` with one
            model, a name defined twice, a joint naming a missing link, an unsupported joint type or pose frame, a
            limit with lower > upper, a non-physical mass or inertia (named).
    """
    if not path.is_file():
        raise SceneError(f"robot.sdf: file {path} does not exist")
    where = f"robot.sdf {path}"
    try:
        root = ET.fromstring(read_bounded(path, where))
    except ET.ParseError as exc:
        raise SceneError(f"{where}: not a readable XML document: {exc}") from None
    check_nesting(root, where)
    element = _model_element(root, path)
    for tag in ("link", "joint"):
        check_count(len(element.findall(tag)), f"{tag}s", where)
        twice = repeated(item.get("name") for item in element.findall(tag))
        if twice:
            raise SceneError(f"robot.sdf {path}: {tag} {twice[0]!r} is defined twice")
    links = {link.name: link for link in (_link(item, path) for item in element.findall("link"))}
    if not links:
        raise SceneError(f"robot.sdf {path}: model {element.get('name')!r} has no <link>")
    if WORLD_LINK in links:
        raise SceneError(f"robot.sdf {path}: a link may not be named {WORLD_LINK!r} (the fixed world)")
    joints = [_joint(item, links) for item in element.findall("joint")]
    static = element.findtext("static", "0").strip() in ("1", "true")
    return SdfModel(element.get("name", path.stem), links, joints, static)


def rpy_of(placement: pin.SE3) -> list[float]:
    """Roll-pitch-yaw [rad] of a placement's rotation."""
    return [float(x) for x in pin.rpy.matrixToRpy(placement.rotation)]
