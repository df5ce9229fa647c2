"""Checks of a URDF document that urdfdom would only refuse, or not see: its size, nesting and depth
(:mod:`.bounds`), its encoding, names, joints between links that exist, moving joints with an axis, joint limits of
finite numbers, finite masses and physical inertias (:mod:`.inertia`).

The robots of example-robot-data (``robot.name``) are taken as published, except for the triangle
inequality of their inertias: the Allegro hand's fingertip links violate it by 25 % (a physically
impossible but positive definite inertia, harmless to the numerics); a URDF of the scene (``robot.urdf``,
``robot.urdf_text``, an object's ``urdf``) is held to it.
"""

from __future__ import annotations

import math
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..errors import SceneError, repeated
from .bounds import check_count, check_depth, check_nesting, check_text_size, read_bounded, tree_depth
from .inertia import check_body

INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
MOVING_JOINTS = ("revolute", "continuous", "prismatic")
AXIS_MIN = 1e-9  # a shorter joint axis is no direction
LIMIT_KEYS = ("lower", "upper", "effort", "velocity")  # a joint's <limit> attributes (urdfdom: unreadable ones unnamed)


def check_links(urdf_text: str | None, urdf_path: Path | None, triangle: bool, owner: str) -> None:
    """The document within the bounds of :mod:`.bounds` (bytes, nesting, links, joints, depth), a file UTF-8 text
    (urdfdom's XML parser, tinyxml2, reads every file as UTF-8 whatever its declaration says), and every link's
    mass [kg] in [0, 1e12], its inertia [kg m^2] positive semidefinite, its principal moments at most 1e12
    (:data:`~pinstab.units.MAX_MAGNITUDE`) and, when ``triangle``, with each principal moment at most the sum of
    the other two. ``owner`` begins every message: the scene key the document was given at (``robot``, or an
    object's ``object 'crate'.urdf``)."""
    where = f"{owner}.urdf_text" if urdf_path is None else f"{owner}: URDF {urdf_path}"
    if urdf_text is not None:
        check_text_size(urdf_text, where)
    text = urdf_text if urdf_text is not None else _utf8(read_bounded(urdf_path, where), where)
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        raise SceneError(f"{owner}: the URDF cannot be read: {exc}") from None
    check_nesting(root, where)
    _check_tree(root, owner)
    links, joints = root.findall("link"), root.findall("joint")
    check_count(len(links), "links", where)
    check_count(len(joints), "joints", where)
    parents = {str(joint.find("child").get("link")): str(joint.find("parent").get("link")) for joint in joints}
    check_depth(tree_depth(parents), where)
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is not None:
            _check_inertial(inertial, f"{owner} link {link.get('name')!r}", triangle)


def _utf8(data: bytes, where: str) -> bytes:
    """``data`` when it is UTF-8 text.

    Raises:
        SceneError: naming ``where`` and the first byte that is not (a binary file, or text in another encoding).
    """
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(
            f"{where}: byte {exc.start} (0x{data[exc.start]:02x}) is not UTF-8: a URDF file is UTF-8 text "
            "(urdfdom reads it so whatever its XML declaration says)"
        ) from None
    return data


def _check_tree(root: ElementTree.Element, owner: str) -> None:
    """Names defined once, joints between links that exist, moving joints with a non-zero axis, the attributes a
    joint's ``<limit>`` gives finite numbers (urdfdom would refuse all but the axis without naming them)."""
    links = [link.get("name") for link in root.findall("link")]
    known = set(links)
    joints = root.findall("joint")
    for kind, names in (("link", links), ("joint", [joint.get("name") for joint in joints])):
        twice = repeated(names)
        if twice:
            raise SceneError(f"{owner}: {kind} {twice[0]!r} is defined twice")
    for joint in joints:
        where = f"{owner} joint {joint.get('name')!r}"
        for end in ("parent", "child"):
            element = joint.find(end)
            link = None if element is None else element.get("link")
            if link not in known:
                raise SceneError(f"{where}: {end} link {link!r} does not exist; links: {', '.join(map(str, links))}")
        axis = joint.find("axis")
        if joint.get("type") in MOVING_JOINTS and axis is not None:
            text = axis.get("xyz", "")
            try:
                direction = np.array([float(x) for x in text.split()])
            except ValueError:
                direction = np.zeros(0)
            if direction.shape != (3,) or not np.isfinite(direction).all() or np.linalg.norm(direction) < AXIS_MIN:
                raise SceneError(f"{where}: axis xyz={text!r} is not a non-zero direction of 3 numbers")
        limit = joint.find("limit")
        for key in LIMIT_KEYS:
            if limit is not None and key in limit.attrib:
                _number(limit, key, f"limit {key}", where)


def _number(element: ElementTree.Element | None, key: str, what: str, where: str) -> float:
    text = None if element is None else element.get(key)
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        raise SceneError(f"{where}: {what} {text!r} is not a finite number")
    return value


def _check_inertial(inertial: ElementTree.Element, where: str, triangle: bool) -> None:
    mass = _number(inertial.find("mass"), "value", "mass", where)
    element = inertial.find("inertia")
    ixx, ixy, ixz, iyy, iyz, izz = (_number(element, key, f"inertia {key}", where) for key in INERTIA_KEYS)
    check_body(mass, np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]), where, triangle)
