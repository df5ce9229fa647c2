"""The MJCF document as the standard library's XML reads it: ``<include>`` files inlined, the compiler's angle
unit and autolimits, attributes through the ``<default>`` classes, numbers and poses of elements.

Includes are bounded before they are read: at most :data:`MAX_INCLUDED_FILES` files, nested at most
:data:`MAX_INCLUDE_DEPTH` deep, :data:`~.bounds.MAX_FILE_BYTES` bytes with the model's file; a file including
itself (directly or not) is refused, naming the chain.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from .bounds import check_nesting, read_bounded

# <include> files of a model: a robot split into files has a few (a MuJoCo Menagerie scene.xml includes its robot's
# file); files that include 10 files each, 3 levels deep, are 1110
MAX_INCLUDED_FILES = 100
MAX_INCLUDE_DEPTH = 10  # includes within includes (a scene that includes a robot that includes its parts: 2)
ORIENTATIONS = ("quat", "axisangle", "euler", "xyaxes", "zaxis")  # the ways an element's orientation is given


@dataclass
class MjcfDocument:
    """An MJCF model read as XML.

    Attributes:
        root: the ``<mujoco>`` element, ``<include>`` elements replaced by the included files' children, an empty
            top ``<default>`` (MuJoCo's class ``main``) added when it has none.
        path: the file read.
        degrees: angles in the file are in degrees (``<compiler angle>``, MuJoCo's default).
        autolimits: a joint with a ``range`` and no ``limited`` is limited (``<compiler autolimits>``).
        eulerseq: the axes of ``euler`` angles (``<compiler eulerseq>``).
        inertiafromgeom: ``true``, ``false`` or ``auto``: whether a body's inertia is computed from its geoms
            (``<compiler inertiafromgeom>``; ``auto``: when it has no ``<inertial>``).
        origins: the elements read from an included file (the top ones of each), with that file.
    """

    root: ET.Element
    path: Path
    degrees: bool = True
    autolimits: bool = True
    eulerseq: str = "xyz"
    inertiafromgeom: str = "auto"
    origins: dict[ET.Element, Path] = field(default_factory=dict)

    def __post_init__(self) -> None:
        top = self.root.find("default")
        if top is None:  # MuJoCo's class main exists in every model: an empty one
            top = ET.Element("default")
            self.root.insert(0, top)
        if top.get("class", "main") != "main":
            raise SceneError(
                f"robot.mjcf {self.path}: the top <default> is class 'main' in MuJoCo, not {top.get('class')!r}"
            )
        self.parents = {child: parent for parent in self.root.iter() for child in parent}
        self.classes: dict[str, ET.Element] = {}
        self._collect(top, "main")
        compiler = self.root.find("compiler")
        if compiler is not None:
            self.degrees = compiler.get("angle", "degree") != "radian"
            self.autolimits = compiler.get("autolimits", "true") == "true"
            self.eulerseq = compiler.get("eulerseq", "xyz")
            self.inertiafromgeom = compiler.get("inertiafromgeom", "auto")
        if self.inertiafromgeom not in ("true", "false", "auto"):
            raise SceneError(
                f"robot.mjcf {self.path}: <compiler inertiafromgeom={self.inertiafromgeom!r}> is not one of true, "
                "false, auto"
            )
        if len(self.eulerseq) != 3 or any(axis not in "xyzXYZ" for axis in self.eulerseq):
            raise SceneError(f"robot.mjcf: <compiler eulerseq={self.eulerseq!r}> is not 3 of x, y, z, X, Y, Z")

    def _collect(self, top: ET.Element, name: str) -> None:
        """The ``<default>`` classes nested in ``top`` (named ``name``), walked without recursion."""
        stack = [(top, name)]
        while stack:
            default, name = stack.pop()
            self.classes[name] = default
            stack.extend((child, child.get("class", name)) for child in default.findall("default"))

    def file_of(self, element: ET.Element) -> Path:
        """The file ``element`` was read from: an included one, or the model's."""
        while element is not None and element not in self.origins:
            element = self.parents.get(element)
        return self.path if element is None else self.origins[element]

    def attribute(self, element: ET.Element, key: str) -> str | None:
        """``key`` of ``element`` as MuJoCo reads it through the defaults (:meth:`attributes`)."""
        return self.attributes(element).get(key)

    def attributes(self, element: ET.Element) -> dict[str, str]:
        """The attributes of ``element`` as MuJoCo reads them: those of its default class (its ``class``, the nearest
        ``childclass`` of the bodies holding it, or ``main``) and of the classes that class is nested in, the nearer
        class first, under the element's own; an orientation given by the element replaces the classes' (one of
        :data:`ORIENTATIONS`), and a ``size`` with fewer numbers than the class's keeps the class's last ones (a
        capsule of ``size="0.05"`` keeps its class's half-length)."""
        tag = self._default_tag(element)
        merged: dict[str, str] = {}
        for default in self.default_chain(element):
            found = default.find(tag)
            if found is not None:
                merged.update(found.attrib)
        own = {key: value for key, value in element.attrib.items() if key not in ("class", "childclass")}
        if any(key in own for key in ORIENTATIONS):
            merged = {key: value for key, value in merged.items() if key not in ORIENTATIONS}
        if "size" in own and "size" in merged:
            given, inherited = own["size"].split(), merged["size"].split()
            own["size"] = " ".join(given + inherited[len(given) :])
        return merged | own

    def default_chain(self, element: ET.Element) -> list[ET.Element]:
        """The ``<default>`` classes that apply to ``element``: ``main`` first, the element's own class (its
        ``class``, else the nearest ``childclass`` of the bodies holding it, else ``main``) last."""
        node = self.classes.get(self._class_of(element))
        chain: list[ET.Element] = []
        while node is not None:
            chain.append(node)
            node = self.parents.get(node) if node is not self.classes.get("main") else None
        return chain[::-1]

    def _default_tag(self, element: ET.Element) -> str:
        """The tag of ``element``'s defaults in a ``<default>`` class: ``equality`` for an equality (``<joint>`` of
        ``<equality>`` is not a joint), ``tendon`` for a tendon, else its own tag."""
        section = self.parents.get(element)
        if section is not None and section.tag in ("equality", "tendon"):
            return section.tag
        return element.tag

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
        SceneError: a file that is not XML, a root other than ``<mujoco>``, a missing or circular include, includes
            or bytes or nesting beyond their bounds (named).
    """
    data = read_bounded(path, "robot.mjcf")
    root = _parse(data, path)
    if root.tag != "mujoco":
        raise SceneError(f"robot.mjcf: {path} has <{root.tag}> at its root, not <mujoco>")
    origins = _inline_includes(root, path, len(data))
    check_nesting(root, f"robot.mjcf {path}", body="body")  # its includes inlined
    return MjcfDocument(root, path, origins=origins)


def _parse(data: bytes, path: Path) -> ET.Element:
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        raise SceneError(f"robot.mjcf: {path} is not valid XML: {exc}") from None


def _inline_includes(root: ET.Element, path: Path, used: int) -> dict[ET.Element, Path]:
    """Replace every ``<include>`` below ``root`` (read from ``path``, ``used`` bytes) by the included file's
    children, in place and in order, walking the elements with a stack and each element's children with a queue
    (an included file's own includes are among them); the included elements with their file.

    Raises:
        SceneError: beyond :data:`MAX_INCLUDED_FILES`, :data:`MAX_INCLUDE_DEPTH` or the bytes' bound, a missing
            file, a file including itself (each naming the including file and the include).
    """
    origins: dict[ET.Element, Path] = {}
    files = 0
    stack: list[tuple[ET.Element, tuple[Path, ...]]] = [(root, (path.resolve(),))]  # element, chain of its files
    while stack:
        element, chain = stack.pop()
        children: list[ET.Element] = []
        queue = deque((child, chain) for child in element)
        while queue:
            child, files_of_child = queue.popleft()
            if child.tag != "include":
                children.append(child)
                stack.append((child, files_of_child))
                continue
            included = path.parent / child.get("file", "")
            where = f"robot.mjcf {files_of_child[-1]}: <include file={child.get('file')!r}>"
            if included.resolve() in files_of_child:
                cycle = " -> ".join(str(item) for item in (*files_of_child, included.resolve()))
                raise SceneError(f"{where}: the file includes itself ({cycle})")
            if len(files_of_child) > MAX_INCLUDE_DEPTH:
                raise SceneError(f"{where}: includes nested more than {MAX_INCLUDE_DEPTH} deep")
            files += 1
            if files > MAX_INCLUDED_FILES:
                raise SceneError(f"{where}: more than {MAX_INCLUDED_FILES} files included into {path}")
            if not included.is_file():
                raise SceneError(f"{where}: included file {included} does not exist")
            data = read_bounded(included, where, used)
            used += len(data)
            items = list(_parse(data, included))
            origins.update((item, included) for item in items)
            queue.extendleft((item, (*files_of_child, included.resolve())) for item in reversed(items))
        element[:] = children
    return origins
