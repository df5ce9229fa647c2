"""MJCF (MuJoCo) robots: ``[robot] mjcf = "file.xml"``.

The kinematic tree, inertias and visual geometry come from Pinocchio 4.1's MJCF parser
(``buildModelFromMJCF``, ``buildGeomFromMJCF``); pinstab reads the rest with the standard library's XML where
that parser is wrong or silent:

- every named ``<body>`` of the file must be in the model (the parser keeps only the first body of
  ``<worldbody>`` and its subtree): a SceneError names the ones it dropped;
- a static first body of ``<worldbody>`` is put at its pose (the parser leaves it at the origin); an
  ``axisangle`` with an axis not of unit length is refused (the parser does not normalize it);
- the parser is given a temporary copy of the file written as MuJoCo reads it (:func:`parser_file`): the
  ``<default>`` classes applied to every element (the parser skips many attributes of a class: a joint's ``pos``,
  a geom's ``type``, ``mass`` and ``pos``), the includes inlined (the parser ignores ``<include>``), the
  ``<compiler>`` first (the parser reads the bodies with only what came before them);
- joints (:mod:`.mjcf_joints`): limits (``range``, ``limited``, in the file's units), ``damping`` and
  ``stiffness``/``springref`` as ``joint-spring`` forces, ``frictionloss`` as ``joint-friction`` forces (dry friction,
  stick and slip), ``armature`` (the parser's rotor inertia);
- the start (:mod:`.mjcf_keyframes`): the keyframe ``robot.keyframe`` names, else the file's first, else MuJoCo's
  qpos0 (the joints at ``ref``);
- ``<equality>``: closures and joint relations with their names (:mod:`.mjcf_equalities`);
- the file within the bounds on size, depth and memory, its masses and inertias physical, checked before the
  parser reads it, and the inertias it compiled after (:mod:`.mjcf_bodies`);
- Pinocchio's remaining refusals quoted, naming the file (a SceneError).

What is not read is said in :attr:`RobotSource.notes`: the ``<option>`` gravity (the scene's ``gravity`` key sets
it), actuators other than a joint's motor, position, velocity or affine general one (:mod:`.mjcf_actuators`),
tendons, sensors, contact pairs (each named), a ball joint's cone limit, the soft-constraint parameters of
equalities, limits and joint friction (pinstab's are rigid).
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from ..memory import named_when_exhausted
from .base import READERS, ReaderOptions, RobotSource
from .mjcf_actuators import read_actuators
from .mjcf_bodies import check_before_parser, check_compiled
from .mjcf_equalities import EqualityReader
from .mjcf_joints import JointReader
from .mjcf_keyframes import read_start
from .mjcf_xml import MjcfDocument, read_document
from .urdf import resolve_file

NOT_READ = ("tendon", "sensor", "contact")  # top-level sections pinstab leaves out (actuators: .mjcf_actuators)
UNIT_AXIS_TOLERANCE = 1e-9


def read_mjcf(robot: dict[str, Any], options: ReaderOptions) -> RobotSource:
    """The robot of ``robot.mjcf`` (a path relative to the scene): model, closures, joint limits, notes.

    Raises:
        SceneError: a missing file, malformed XML, a file Pinocchio cannot read, a body it dropped, an equality
            naming a missing body, site or joint, or one pinstab cannot hold, a file beyond a bound, a non-physical
            mass or inertia (named).
        MemoryBudgetError: the parser's Data would not fit the memory budget.
    """
    path = resolve_file(robot, "mjcf", options)
    document = read_document(path)
    check_before_parser(document, options.free_flyer)
    try:
        with parser_file(document) as parsed, named_when_exhausted(f"Pinocchio's MJCF parser on {path}"):
            if options.free_flyer:
                model = pin.buildModelFromMJCFAndRootJoint(str(parsed), pin.JointModelFreeFlyer(), "root_joint")
            else:
                model = pin.buildModelFromMJCF(str(parsed))
    except (ValueError, RuntimeError, IndexError) as exc:  # IndexError: its std::out_of_range
        raise SceneError(f"robot.mjcf: Pinocchio's MJCF parser cannot read {path}: {_parser_message(exc)}") from None
    _check_bodies(document, model)
    check_compiled(document, model)
    _check_axis_angles(document)
    _place_root(document, model)
    joints = JointReader(document, model)
    joints.read()
    equalities = EqualityReader(document, model)
    equalities.read()
    notes = joints.notes + equalities.notes + _not_read(document)
    keyframe = robot.get("keyframe")
    if keyframe is not None and not isinstance(keyframe, str):
        raise SceneError(f"robot.keyframe must be the name of a <key> of {path}, got {keyframe!r}")
    start = read_start(document, model, keyframe, notes)
    notes.append(f"the start is {start.label} (robot.keyframe or --keyframe names another key)")
    scalar = {name for name, joint in zip(model.names, model.joints, strict=True) if joint.nv == 1}
    forces = joints.forces + read_actuators(document, scalar, robot.get("ctrl"), start.ctrl, notes)
    tables = equalities.tables | ({"forces": forces} if forces else {})

    def geometry(full: pin.Model, kind: pin.GeometryType, search: list[str]) -> pin.GeometryModel:
        with parser_file(document) as parsed:  # placed by the model's body frames; meshes by path
            return pin.buildGeomFromMJCF(full, str(parsed), kind)

    return RobotSource(
        model,
        "mjcf",
        path,
        package_dirs=[str(path.parent)],
        tables=tables,
        notes=notes,
        geometry=geometry,
        start=(start.q, start.v),
    )


def _parser_message(exc: Exception) -> str:
    """Pinocchio's own message in ``exc``, without the source file, function and line it prefixes."""
    text = str(exc)
    return text.split("message:", 1)[-1].strip() or text


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


@contextmanager
def parser_file(document: MjcfDocument) -> Iterator[Path]:
    """The file Pinocchio's MJCF parser is given: a temporary copy of the model (removed on leaving) written as MuJoCo
    reads it, where the parser alone would read it otherwise:

    - the ``<default>`` classes applied to every element (:meth:`~.mjcf_xml.MjcfDocument.attributes`: nested
      classes, ``childclass``, ``class``, MuJoCo's ``main``), written on the element, the classes removed: the parser
      skips many attributes of a class (a joint's ``pos``, a geom's ``type``, ``mass`` and ``pos``: a gripper's
      finger axes 1.9 cm off, a body's mass 76 % off); a ``pos`` beside a ``fromto`` is left out (the ``fromto``
      places the geom, as in MuJoCo);
    - the included files inlined (the parser ignores ``<include>``);
    - the ``<compiler>`` put first (the parser reads the bodies with only what came before them: angles in degrees
      where the compiler says radians);
    - the mesh and texture folders made absolute (as MuJoCo reads them: relative to the model's folder);
    - the keyframes left out (read by :mod:`.mjcf_keyframes`, which names a key of a wrong size).
    """
    root = ET.Element(document.root.tag, document.root.attrib)
    if document.root.find("compiler") is None:
        root.append(ET.Element("compiler", _absolute_folders({}, document.path.parent)))
    for child in sorted(document.root, key=lambda child: child.tag != "compiler"):  # stable: the rest in order
        if child.tag == "compiler":
            compiler = ET.SubElement(root, "compiler", _absolute_folders(child.attrib, document.path.parent))
            compiler.extend(child)
        elif child.tag not in ("default", "keyframe"):  # keyframes: read by pinstab (.mjcf_keyframes)
            root.append(_with_defaults(document, child))
    with tempfile.TemporaryDirectory(prefix="pinstab-mjcf-") as temporary:
        parsed = Path(temporary) / document.path.name
        parsed.write_text(_xml_text(root), encoding="utf-8")
        yield parsed


def _with_defaults(document: MjcfDocument, top: ET.Element) -> ET.Element:
    """A copy of ``top`` and the elements below it, each with the attributes MuJoCo reads through the defaults,
    without ``class`` and ``childclass`` (walked without recursion)."""
    copied = ET.Element(top.tag)
    stack = [(top, copied)]
    while stack:
        element, copy = stack.pop()
        attributes = document.attributes(element)
        if "fromto" in attributes:
            attributes.pop("pos", None)
        copy.attrib.update(attributes)
        copy.text, copy.tail = element.text, element.tail
        for child in element:
            stack.append((child, ET.SubElement(copy, child.tag)))
    return copied


def _absolute_folders(attributes: dict[str, str], folder: Path) -> dict[str, str]:
    """A ``<compiler>``'s attributes with its asset, mesh and texture folders absolute (from ``folder``, the
    model's), the mesh and texture ones given (``folder``) when no asset folder stands for them."""
    absolute = dict(attributes)
    for key in ("assetdir", "meshdir", "texturedir"):
        given = attributes.get(key)
        if given is not None or (key != "assetdir" and "assetdir" not in attributes):
            absolute[key] = str(folder / (given or ""))
    return absolute


def _xml_text(root: ET.Element) -> str:
    """The XML text of ``root`` written without recursion (``ET.tostring`` takes a Python frame per level: an MJCF
    may nest its bodies :data:`~.bounds.MAX_TREE_DEPTH` deep, as deep as Python's recursion limit)."""
    out: list[str] = []
    stack: list[tuple[ET.Element, bool]] = [(root, False)]
    while stack:
        element, closing = stack.pop()
        if closing:
            out.append(f"</{element.tag}>{escape(element.tail or '')}")
            continue
        attributes = "".join(f" {key}={quoteattr(value)}" for key, value in element.attrib.items())
        out.append(f"<{element.tag}{attributes}>{escape(element.text or '')}")
        stack.append((element, True))
        stack.extend((child, False) for child in reversed(element))
    return "".join(out)


def _not_read(document: MjcfDocument) -> list[str]:
    """Notes on the file's sections pinstab leaves out (:data:`NOT_READ`, each element named) and its gravity."""
    notes = []
    for tag in NOT_READ:
        elements = [item for section in document.root.findall(tag) for item in section]
        if elements:
            named = ", ".join(f"{item.tag} {item.get('name', f'number {i}')!r}" for i, item in enumerate(elements))
            notes.append(f"<{tag}> not read: {named}")
    option = document.root.find("option")
    if option is not None and option.get("gravity") is not None:
        notes.append(f"<option gravity={option.get('gravity')!r}> not read: the scene's gravity key sets gravity")
    return notes


READERS.register("mjcf", read_mjcf, summary="an MJCF (MuJoCo) file (robot.mjcf)")
