"""The bodies of an MJCF file checked before Pinocchio's MJCF parser reads them, and the inertias it compiled.

Before (the bodies' nesting is bounded as the document is read, :mod:`.mjcf_xml`): a ``<body>`` in
``<worldbody>``, a free joint alone in its body, an ``<inertial>`` in every body when ``<compiler
inertiafromgeom="false">``, every body's geom of a type and sizes the parser weighs (it fails on the others, naming
none, or reads missing sizes as unwritten memory); the bodies and joints within
:data:`~.bounds.MAX_BODIES`, the one Pinocchio ``Data`` the parser
builds within the memory budget (its resident size grows with nv^3: 0.9 GB at nv = 300, 33 GB at nv = 1000),
every ``<inertial>``'s mass and inertia physical (the parser runs a mass of -0.5 kg as 0 and an inertia diagonal
of (-1, 1, 1) as (0, 1, 1); MuJoCo refuses both), every geom's mass, density and sizes, from which the inertia of a
body without ``<inertial>`` is computed (``<compiler inertiafromgeom>``), not negative (the parser makes a body of
negative mass of a geom of negative density; MuJoCo refuses it). After: the inertia of every joint's bodies as the
parser compiled them, by the same check (:func:`~.inertia.check_body`).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from ..memory import data_bytes, require
from .bounds import check_count
from .inertia import check_body, check_nonnegative
from .mjcf_xml import MjcfDocument

JOINT_DOFS = {"hinge": 1, "slide": 1, "ball": 3, "free": 6}  # MJCF joint type -> velocities
GEOM_QUANTITIES = (("mass", "kg"), ("density", "kg/m^3"))
# the numbers of the attributes Pinocchio's MJCF parser reads, as MuJoCo requires them: the parser reads fewer as
# memory it never wrote (pos="1 2": a z of 2e243) and ignores more, where MuJoCo refuses both
NUMBERS = {"pos": 3, "quat": 4, "axisangle": 4, "euler": 3, "xyaxes": 6, "zaxis": 3, "axis": 3, "range": 2}
NUMBERS |= {key: 1 for key in ("ref", "springref", "stiffness", "damping", "armature", "frictionloss")}
NUMBERS |= {"actuatorfrcrange": 2}  # a joint's effort bounds (Pinocchio read "nan nan" as 7e-310)
NUMBERS |= {"mass": 1, "density": 1, "diaginertia": 3, "fullinertia": 6, "fromto": 6, "rgba": 4}
# MJCF geom type -> the sizes Pinocchio's MJCF parser reads of it (as MuJoCo requires them; the parser reads
# missing ones as memory it never wrote: a box of size="0.1 0.2" weighed 1.5e-320 kg); a mesh's size is not read
GEOM_SIZES = {"sphere": 1, "capsule": 2, "cylinder": 2, "ellipsoid": 3, "box": 3, "plane": 3, "mesh": 0}
FROMTO_TYPES = ("capsule", "cylinder", "box", "ellipsoid")  # the types a fromto places; it then gives their length
NUMBERED = ("body", "inertial", "joint", "freejoint", "geom", "site")  # elements of the tree, or their defaults


def joint_kind(document: MjcfDocument, joint: ET.Element, where: str) -> str:
    """The type of a ``<joint>`` (through the defaults; ``hinge`` when none) or ``free`` for a ``<freejoint>``.

    Raises:
        SceneError: an unknown type, naming the joint and the types.
    """
    given = "free" if joint.tag == "freejoint" else document.attribute(joint, "type")
    kind = "hinge" if given is None else given  # type="" is no type: MuJoCo refuses it, as pinstab does
    if kind not in JOINT_DOFS:
        raise SceneError(f"{where}: unknown type {kind!r}; MJCF joint types: {', '.join(JOINT_DOFS)}")
    return kind


def check_before_parser(document: MjcfDocument, free_flyer: bool) -> None:
    """What the file asks of Pinocchio's MJCF parser (see the module docstring), checked before it runs.

    Raises:
        SceneError: a bound passed or a non-physical value, naming the file, the body or geom and the value.
        MemoryBudgetError: the parser's Data would not fit the memory budget.
    """
    where = f"robot.mjcf {document.path}"
    worldbody = document.root.find("worldbody")
    if worldbody is None or worldbody.find("body") is None:
        raise SceneError(
            f"{where}: <worldbody> holds no <body> (Pinocchio's MJCF parser builds the robot from the first <body> "
            "of <worldbody> and its subtree): put the robot's bodies in a <body> of <worldbody>"
        )
    bodies = list(worldbody.iter("body"))
    joints = [j for j in worldbody.iter() if j.tag in ("joint", "freejoint")]
    check_count(len(bodies), "bodies", where)
    check_count(len(joints), "joints", where)
    nv = 6 * free_flyer + sum(JOINT_DOFS[joint_kind(document, j, _name(document, j))] for j in joints)
    require(
        {"the Pinocchio Data its MJCF parser builds": data_bytes(nv, len(joints) + 1, tensors=True)},
        f"Pinocchio's MJCF parser on {document.path} ({nv} velocities)",
        remedy="give a model of fewer joints",
    )
    for element in document.root.iter():
        if element.tag in NUMBERED:
            _check_numbers(document, element, _name(document, element))
        for key in ("class", "childclass"):
            if element.get(key) is not None and element.tag != "default" and element.get(key) not in document.classes:
                raise SceneError(
                    f"{_name(document, element)}: {key}={element.get(key)!r} is not a default class; classes: "
                    f"{', '.join(document.classes)}"
                )
    for body in bodies:
        _check_joints(document, body)
        inertial = body.find("inertial")
        if inertial is not None:
            _check_inertial(document, inertial, _name(document, body))
        elif document.inertiafromgeom == "false":
            raise SceneError(
                f'{_name(document, body)}: no <inertial>, and <compiler inertiafromgeom="false"> does not compute '
                "its inertia from its geoms: give the body an <inertial> (mass, diaginertia or fullinertia), or set "
                'inertiafromgeom to "auto" or "true"'
            )
        for geom in body.findall("geom"):
            _check_shape(document, geom, _name(document, geom))
    for geom in worldbody.iter("geom"):
        _check_geom(document, geom, _name(document, geom))


def _check_joints(document: MjcfDocument, body: ET.Element) -> None:
    """A free joint is the only joint of its body, as MuJoCo requires (Pinocchio's MJCF parser makes one
    composite joint of a body's joints and holds no free joint in it)."""
    joints = [joint for joint in body if joint.tag in ("joint", "freejoint")]
    for joint in joints:
        where = _name(document, joint)
        if len(joints) > 1 and joint_kind(document, joint, where) == "free":
            raise SceneError(
                f"{where}: a free joint must be the only joint of its body {body.get('name')!r} (it has "
                f"{len(joints)}), as MuJoCo requires: remove the other joints, or replace this one by a hinge, slide "
                "or ball joint"
            )


def check_compiled(document: MjcfDocument, model: pin.Model) -> None:
    """The inertia of each joint's bodies as Pinocchio's parser compiled them (from ``<inertial>`` or the geoms),
    by :func:`~.inertia.check_body` (no triangle inequality: a sum of bodies' inertias about one point).

    Raises:
        SceneError: naming the file, the joint and the value.
    """
    for joint in range(model.njoints):
        inertia = model.inertias[joint]
        bodies = "the bodies fixed to the world" if joint == 0 else f"the bodies on joint {model.names[joint]!r}"
        where = f"robot.mjcf {document.path}: {bodies} (as Pinocchio's MJCF parser compiled them)"
        placement = model.jointPlacements[joint].homogeneous
        if not (np.isfinite(placement).all() and np.isfinite(inertia.lever).all()):
            raise SceneError(f"{where}: a placement or centre of mass is not finite")
        check_body(inertia.mass, inertia.inertia, where, triangle=False)


def _name(document: MjcfDocument, element: ET.Element) -> str:
    """``robot.mjcf <file> <tag> '<name>'`` (an unnamed element: ``<tag> number <i> of body '<name>'``, or of its
    default class), the file the element was read from (the model's or an included one)."""
    label = f"{element.tag} {element.get('name')!r}"
    parent = document.parents.get(element)
    if element.get("name") is None and parent is not None:
        index = [item for item in parent if item.tag == element.tag].index(element)
        named = parent.get("name", parent.get("class", "main" if parent.tag == "default" else None))
        label = f"{element.tag} number {index} of {parent.tag} {named!r}"
    return f"robot.mjcf {document.file_of(element)} {label}"


def _check_numbers(document: MjcfDocument, element: ET.Element, where: str) -> None:
    """The element's own attributes of :data:`NUMBERS`: each as many finite numbers as MuJoCo requires; its
    ``size`` (a geom's or a site's) 1 to 3 of them, not negative."""
    for key in element.attrib:
        if key in NUMBERS:
            document.numbers(element, key, NUMBERS[key], where)
    text = document.attribute(element, "size") if "size" in element.attrib else None  # with its class's last ones
    if text is not None and element.tag in ("geom", "site"):
        count = len(text.split())
        if not 1 <= count <= 3:
            raise SceneError(f"{where}: size={text!r} is not 1 to 3 numbers")
        for value in document.numbers(element, "size", count, where):
            check_nonnegative(float(value), f"{where}: size", "m")


def _check_shape(document: MjcfDocument, geom: ET.Element, where: str) -> None:
    """A body's geom as Pinocchio's MJCF parser reads it to compute the body's inertia (through the defaults): a
    type of :data:`GEOM_SIZES`, its sizes given (the radius only with a ``fromto``), a ``fromto`` only on the types
    of :data:`FROMTO_TYPES` and not beside a ``pos`` of the geom, no ``shellinertia``."""
    kind = document.attribute(geom, "type")
    kind = "sphere" if kind is None else kind  # MuJoCo's default type
    if kind not in GEOM_SIZES:
        raise SceneError(
            f"{where}: type {kind!r} is not a geom type Pinocchio's MJCF parser reads (hfield and sdf not among "
            f"them); types: {', '.join(GEOM_SIZES)}"
        )
    fromto = document.attribute(geom, "fromto") is not None
    if fromto and kind not in FROMTO_TYPES:
        raise SceneError(f"{where}: a fromto places a {', '.join(FROMTO_TYPES)}, not a {kind}: give it pos")
    if "fromto" in geom.attrib and "pos" in geom.attrib:  # the parser's test: on the element, not its defaults
        raise SceneError(f"{where}: both pos and fromto given (Pinocchio's MJCF parser refuses them): give one")
    if document.attribute(geom, "shellinertia") is not None:
        raise SceneError(f"{where}: shellinertia is not read by Pinocchio's MJCF parser: remove it")
    needed = 1 if fromto else GEOM_SIZES[kind]
    given = (document.attribute(geom, "size") or "").split()
    if len(given) < needed:
        raise SceneError(
            f"{where}: a {kind} {'with a fromto ' if fromto else ''}needs {needed} numbers in size, "
            f"size={' '.join(given)!r} gives {len(given)}"
        )


def _check_inertial(document: MjcfDocument, inertial: ET.Element, where: str) -> None:
    """An ``<inertial>``: ``mass`` and ``diaginertia`` (ixx iyy izz) or ``fullinertia`` (ixx iyy izz ixy ixz iyz),
    held to the triangle inequality as MuJoCo holds them."""
    mass = float(document.numbers(inertial, "mass", 1, f"{where} <inertial>")[0])
    if inertial.get("fullinertia") is not None:
        xx, yy, zz, xy, xz, yz = document.numbers(inertial, "fullinertia", 6, f"{where} <inertial>")
        inertia = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    elif inertial.get("diaginertia") is not None:
        inertia = np.diag(document.numbers(inertial, "diaginertia", 3, f"{where} <inertial>"))
    else:
        raise SceneError(
            f"{where}: <inertial> gives neither diaginertia nor fullinertia (Pinocchio's MJCF parser would take "
            "1 kg m^2 about each axis, MuJoCo 0)"
        )
    check_body(mass, inertia, where, triangle=True)


def _check_geom(document: MjcfDocument, geom: ET.Element, where: str) -> None:
    """A geom's ``mass`` [kg] and ``density`` [kg/m^3] (through the defaults: MuJoCo applies them, Pinocchio's
    parser not always) not negative and within the ceiling."""
    for key, unit in GEOM_QUANTITIES:
        if document.attribute(geom, key) is not None:
            check_nonnegative(float(document.numbers(geom, key, 1, where)[0]), f"{where}: {key}", unit)
