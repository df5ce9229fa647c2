"""The MJCF document as the standard library's XML reads it: ``<include>`` files inlined, the compiler's angle
unit and autolimits, attributes through the ``<default>`` classes, numbers and poses of elements."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import SceneError

MAX_INCLUDES = 100  # deeper than any model: a file including itself


@dataclass
class MjcfDocument:
    """An MJCF model read as XML.

    Attributes:
        root: the ``<mujoco>`` element, ``<include>`` elements replaced by the included files' children.
        path: the file read.
        degrees: angles in the file are in degrees (``<compiler angle>``, MuJoCo's default).
        autolimits: a joint with a ``range`` and no ``limited`` is limited (``<compiler autolimits>``).
        eulerseq: the axes of ``euler`` angles (``<compiler eulerseq>``).
    """

    root: ET.Element
    path: Path
    degrees: bool = True
    autolimits: bool = True
    eulerseq: str = "xyz"

    def __post_init__(self) -> None:
        self.parents = {child: parent for parent in self.root.iter() for child in parent}
        self.classes: dict[str, ET.Element] = {}
        top = self.root.find("default")
        if top is not None:
            self._collect(top, "main")
        compiler = self.root.find("compiler")
        if compiler is not None:
            self.degrees = compiler.get("angle", "degree") != "radian"
            self.autolimits = compiler.get("autolimits", "true") == "true"
            self.eulerseq = compiler.get("eulerseq", "xyz")
        if len(self.eulerseq) != 3 or any(axis not in "xyzXYZ" for axis in self.eulerseq):
            raise SceneError(f"robot.mjcf: <compiler eulerseq={self.eulerseq!r}> is not 3 of x, y, z, X, Y, Z")

    def _collect(self, default: ET.Element, name: str) -> None:
        self.classes[name] = default
        for child in default.findall("default"):
            self._collect(child, child.get("class", name))

    def attribute(self, element: ET.Element, key: str) -> str | None:
        """``key`` of ``element``, else of its default class (its ``class``, the nearest ``childclass`` of the
        bodies holding it, or ``main``) and the classes that class is nested in."""
        if key in element.attrib:
            return element.get(key)
        node = self.classes.get(self._class_of(element))
        while node is not None:
            default = node.find(element.tag)
            if default is not None and key in default.attrib:
                return default.get(key)
            node = self.parents.get(node) if node is not self.classes.get("main") else None
        return None

    def _class_of(self, element: ET.Element) -> str:
        if "class" in element.attrib:
            return str(element.get("class"))
        parent = self.parents.get(element)
        while parent is not None:
            if "childclass" in parent.attrib:
                return str(parent.get("childclass"))
            parent = self.parents.get(parent)
        return "main"

    def numbers(self, element: ET.Element, key: str, size: int, where: str, default: list[float] | None = None):
        """The ``size`` numbers of attribute ``key`` (through the defaults), or ``default``.

        Raises:
            SceneError: missing without a default, or not ``size`` finite numbers.
        """
        text = self.attribute(element, key)
        if text is None:
            if default is None:
                raise SceneError(f"{where}: attribute {key!r} is required")
            return np.array(default, dtype=float)
        try:
            values = np.array([float(x) for x in text.split()])
        except ValueError:
            values = np.zeros(0)
        if values.shape != (size,) or not np.isfinite(values).all():
            raise SceneError(f"{where}: {key}={text!r} is not {size} finite numbers")
        return values

    def pose(self, element: ET.Element, where: str) -> pin.SE3:
        """The pose of a body or site in its parent's frame: ``pos`` [m] and ``quat`` (w x y z), ``euler`` (the
        compiler's ``eulerseq``: lower case rotating axes, upper case fixed ones) or ``axisangle``.

        Raises:
            SceneError: an orientation given by ``xyaxes`` or ``zaxis``, or not a rotation.
        """
        for other in ("xyaxes", "zaxis"):
            if self.attribute(element, other) is not None:
                raise SceneError(f"{where}: an orientation given by {other} is not read; give it as quat or euler")
        position = self.numbers(element, "pos", 3, where, [0.0, 0.0, 0.0])
        if self.attribute(element, "euler") is not None:
            rotation = np.eye(3)
            angles = self.numbers(element, "euler", 3, where) * self.angle_factor()
            for axis, angle in zip(self.eulerseq, angles, strict=True):
                turn = pin.exp3(angle * np.eye(3)["xyz".index(axis.lower())])
                rotation = rotation @ turn if axis.islower() else turn @ rotation
            return pin.SE3(rotation, position)
        if self.attribute(element, "axisangle") is not None:
            axis_angle = self.numbers(element, "axisangle", 4, where)
            norm = np.linalg.norm(axis_angle[:3])
            if norm == 0.0:
                raise SceneError(f"{where}: the axis of axisangle is zero")
            return pin.SE3(pin.exp3(axis_angle[:3] / norm * axis_angle[3] * self.angle_factor()), position)
        w, x, y, z = self.numbers(element, "quat", 4, where, [1.0, 0.0, 0.0, 0.0])
        quaternion = pin.Quaternion(w, x, y, z)
        if quaternion.norm() == 0.0:
            raise SceneError(f"{where}: quat is zero")
        return pin.SE3(quaternion.normalized().matrix(), position)

    def angle_factor(self) -> float:
        """Radians per angle unit of the file."""
        return math.pi / 180.0 if self.degrees else 1.0


def read_document(path: Path) -> MjcfDocument:
    """The MJCF file ``path`` with its includes (paths relative to ``path``'s folder, as MuJoCo reads them).

    Raises:
        SceneError: a file that is not XML, a root other than ``<mujoco>``, a missing or circular include.
    """
    root = _parse(path)
    if root.tag != "mujoco":
        raise SceneError(f"robot.mjcf: {path} has <{root.tag}> at its root, not <mujoco>")
    _inline_includes(root, path.parent, 0)
    return MjcfDocument(root, path)


def _parse(path: Path) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise SceneError(f"robot.mjcf: {path} is not valid XML: {exc}") from None


def _inline_includes(element: ET.Element, folder: Path, depth: int) -> None:
    for index, child in reversed(list(enumerate(element))):
        if child.tag != "include":
            _inline_includes(child, folder, depth)
            continue
        if depth >= MAX_INCLUDES:
            raise SceneError(f"robot.mjcf: includes nested deeper than {MAX_INCLUDES} (a file includes itself?)")
        path = folder / child.get("file", "")
        if not path.is_file():
            raise SceneError(f"robot.mjcf: included file {path} does not exist")
        included = _parse(path)
        _inline_includes(included, folder, depth + 1)
        element.remove(child)
        for offset, item in enumerate(included):
            element.insert(index + offset, item)
