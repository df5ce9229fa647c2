"""MJCF (MuJoCo) robots: ``[robot] mjcf = "file.xml"``.

The kinematic tree, inertias and visual geometry come from Pinocchio 4.1's MJCF parser
(``buildModelFromMJCF``, ``buildGeomFromMJCF``); pinstab reads the rest with the standard library's XML where
that parser is wrong or silent:

- every named ``<body>`` of the file must be in the model (the parser keeps only the first body of
  ``<worldbody>`` and its subtree): a SceneError names the ones it dropped;
- a static first body of ``<worldbody>`` is put at its pose (the parser leaves it at the origin); an
  ``axisangle`` with an axis not of unit length is refused (the parser does not normalize it);
- joint limits: ``range`` and ``limited`` (``<compiler autolimits>``, ``<default>`` classes), a hinge's range in
  the file's angle unit, a slide's in metres (the parser also converts a slide's range as an angle and limits a
  joint with ``limited="false"``); an unlimited joint has infinite limits;
- ``<equality>``: closures and joint relations with their names (:mod:`.mjcf_equalities`).

What is not read is said in :attr:`RobotSource.notes`: the ``<option>`` gravity (the scene's ``gravity`` key sets
it), actuators, tendons, sensors, contact pairs, a ball joint's cone limit, the soft-constraint parameters.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from .base import READERS, ReaderOptions, RobotSource
from .mjcf_equalities import EqualityReader
from .mjcf_xml import MjcfDocument, read_document
from .urdf import resolve_file

NOT_READ = ("actuator", "tendon", "sensor", "contact")  # top-level sections pinstab leaves out
UNIT_AXIS_TOLERANCE = 1e-9
SCALAR_JOINTS = {"hinge": 1, "slide": 1, "ball": 4, "free": 7}  # MJCF joint type -> configuration size


def read_mjcf(robot: dict[str, Any], options: ReaderOptions) -> RobotSource:
    """The robot of ``robot.mjcf`` (a path relative to the scene): model, closures, joint limits, notes.

    Raises:
        SceneError: a missing file, malformed XML, a file Pinocchio cannot read, a body it dropped, an equality
            naming a missing body, site or joint, or one pinstab cannot hold (named).
    """
    path = resolve_file(robot, "mjcf", options)
    document = read_document(path)
    try:
        if options.free_flyer:
            model = pin.buildModelFromMJCFAndRootJoint(str(path), pin.JointModelFreeFlyer(), "root_joint")
        else:
            model = pin.buildModelFromMJCF(str(path))
    except (ValueError, RuntimeError) as exc:
        raise SceneError(f"robot.mjcf: Pinocchio cannot read {path}: {exc}") from None
    _check_bodies(document, model)
    _check_axis_angles(document)
    _place_root(document, model)
    notes = _joint_limits(document, model)
    equalities = EqualityReader(document, model)
    equalities.read()
    notes += equalities.notes + _not_read(document)

    def geometry(full: pin.Model, kind: pin.GeometryType, search: list[str]) -> pin.GeometryModel:
        return pin.buildGeomFromMJCF(full, str(path), kind)  # placed by the model's body frames; meshes by path

    return RobotSource(
        model, "mjcf", path, package_dirs=[str(path.parent)], tables=equalities.tables, notes=notes, geometry=geometry
    )


def _check_bodies(document: MjcfDocument, model: pin.Model) -> None:
    """Every named body of the file is a body frame of the model."""
    dropped = [
        str(body.get("name"))
        for body in document.root.iter("body")
        if body.get("name") and not model.existFrame(str(body.get("name")), pin.FrameType.BODY)
    ]
    if dropped:
        raise SceneError(
            f"robot.mjcf: Pinocchio's MJCF parser dropped the bodies {', '.join(map(repr, dropped))} of "
            f"{document.path} (it reads only the first body of <worldbody> and its subtree): put every body of "
            "<worldbody> under one body"
        )


def _check_axis_angles(document: MjcfDocument) -> None:
    """Refuse an ``axisangle`` whose axis is not a unit vector: Pinocchio's parser does not normalize it (a body's
    frame turned by another angle about another axis)."""
    for element in document.root.iter():
        if element.tag in ("body", "site", "geom", "frame") and element.get("axisangle") is not None:
            where = f"robot.mjcf {element.tag} {element.get('name')!r}"
            axis = document.numbers(element, "axisangle", 4, where)[:3]
            if abs(np.linalg.norm(axis) - 1.0) > UNIT_AXIS_TOLERANCE:
                raise SceneError(
                    f"{where}: the axis of axisangle={element.get('axisangle')!r} is not of unit length, which "
                    "Pinocchio's MJCF parser reads wrong: give a unit axis"
                )


def _place_root(document: MjcfDocument, model: pin.Model) -> None:
    """Put a static first body of ``<worldbody>`` at its pose: Pinocchio's parser leaves it at the origin (a first
    body with joints it places right)."""
    root = document.root.find("worldbody/body")
    if root is None or root.find("joint") is not None or root.find("freejoint") is not None:
        return
    pose = document.pose(root, f"robot.mjcf body {root.get('name')!r}")
    for joint in range(1, model.njoints):
        if model.parents[joint] == 0:
            model.jointPlacements[joint] = pose * model.jointPlacements[joint]
    for index in range(1, len(model.frames)):
        frame = model.frames[index]
        if frame.parentJoint == 0:
            frame.placement = pose * frame.placement
            model.frames[index] = frame


def _joint_limits(document: MjcfDocument, model: pin.Model) -> list[str]:
    """Write the file's joint limits into ``model``'s position limits; notes on what could not be."""
    notes: list[str] = []
    for body in document.root.iter("body"):
        joints = [j for j in body if j.tag in ("joint", "freejoint")]
        names = [str(j.get("name")) for j in joints]
        if len(joints) > 1:
            notes.append(f"body {body.get('name')!r}: its joints {', '.join(names)} are one composite joint")
        offset = 0
        for joint, name in zip(joints, names, strict=True):
            kind = "free" if joint.tag == "freejoint" else document.attribute(joint, "type") or "hinge"
            where = f"robot.mjcf joint {name!r}"
            if kind not in SCALAR_JOINTS:
                raise SceneError(f"{where}: unknown type {kind!r}; MJCF joint types: {', '.join(SCALAR_JOINTS)}")
            index = _q_index(model, name, names[0], offset)
            offset += SCALAR_JOINTS[kind]
            limits = _limits(document, joint, kind, where)
            if limits is None:
                continue
            if kind == "ball":
                notes.append(f"joint {name!r}: the cone limit of a ball joint is not read")
            elif index is None:
                notes.append(f"joint {name!r}: not found in Pinocchio's model, its range is not read")
            else:
                model.lowerPositionLimit[index], model.upperPositionLimit[index] = limits
    return notes


def _limits(document: MjcfDocument, joint: ET.Element, kind: str, where: str) -> tuple[float, float] | None:
    """The joint's (lower, upper) position limits [rad or m], (-inf, inf) when unlimited, None for a free joint."""
    if kind == "free":
        return None
    limited = document.attribute(joint, "limited") or "auto"
    has_range = document.attribute(joint, "range") is not None
    if limited not in ("true", "false", "auto"):
        raise SceneError(f"{where}: limited={limited!r} is not one of true, false, auto")
    if limited == "false" or (limited == "auto" and not (document.autolimits and has_range)):
        return -np.inf, np.inf
    lower, upper = document.numbers(joint, "range", 2, where)
    if lower > upper:
        raise SceneError(f"{where}: range lower {lower} > upper {upper}")
    factor = document.angle_factor() if kind in ("hinge", "ball") else 1.0
    return lower * factor, upper * factor


def _q_index(model: pin.Model, name: str, first: str, offset: int) -> int | None:
    """The configuration index of joint ``name``: its own joint, or its place in the body's composite joint."""
    for joint_name, start in ((name, 0), (f"Composite_{first}", offset)):
        if model.existJointName(joint_name):
            return model.joints[model.getJointId(joint_name)].idx_q + start
    return None


def _not_read(document: MjcfDocument) -> list[str]:
    notes = [f"<{tag}> not read" for tag in NOT_READ if document.root.find(tag) is not None]
    option = document.root.find("option")
    if option is not None and option.get("gravity") is not None:
        notes.append(f"<option gravity={option.get('gravity')!r}> not read: the scene's gravity key sets gravity")
    return notes


READERS.register("mjcf", read_mjcf, summary="an MJCF (MuJoCo) file (robot.mjcf)")
