"""Rigid objects a scene adds to the robot: boxes, spheres, cylinders or a one-body URDF, each a
free-flyer body of the Pinocchio model, with its mass and inertia (from a density, or given), its
contact geometry (coal shapes, for fingertip contacts) and its visuals.

Scene table ``[[objects]]``: ``name``, ``shape`` (``box`` with ``size = [x, y, z]``, ``sphere`` with
``radius``, ``cylinder`` with ``radius`` and ``length`` along its z axis, or ``urdf`` with ``urdf``, a
file whose links are all fixed to one another), exactly one of ``density`` [kg/m^3] or ``mass`` [kg]
for shapes (optional ``inertia = [ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2] about the centre with
``mass``), ``position`` [m] and ``rpy`` [rad] of the object frame in the world, ``color`` (RGBA). The
object's free-flyer joint and its body frame are both named after the object; its configuration is
``[x, y, z, qx, qy, qz, qw]`` and its velocity the body twist (linear first) in the object frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from ..errors import SceneError, choices
from ..tables import check_keys, coordinates, list_of_tables, placement, vector
from ..units import (
    MAX_MAGNITUDE,
    MIN_LENGTH,
    MIN_LENGTH_REASON,
    MIN_MASS,
    MIN_MASS_REASON,
    quantity,
    within_ceiling,
)

SHAPES = ("box", "sphere", "cylinder", "urdf")
OBJECT_KEYS = {"name", "shape", "size", "radius", "length", "density", "mass", "inertia", "position", "rpy", "color"}
URDF_OBJECT_KEYS = {"name", "shape", "urdf", "position", "rpy", "color"}
DEFAULT_COLOR = (0.85, 0.55, 0.15, 1.0)
SI_UNITS = {"length": "m", "mass": "kg", "density": "kg/m^3"}
# reads the URDF file an object's ``urdf`` names (the value, and where it is given, e.g. ``object 'crate'.urdf``) into
# its model, collision and visual geometry, or raises a SceneError naming where. The scene hands in the URDF reader of
# :mod:`pinstab.readers` (a layer above this one), so that an object's file meets every check of a robot's file
UrdfReader = Callable[[Any, str], tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]]


@dataclass
class SceneObject:
    """A rigid object of the scene.

    Attributes:
        name: the object's name (also its joint's and body frame's).
        shape: one of :data:`SHAPES`.
        joint: index of its free-flyer joint in the scene model. frame: index of its body frame.
        idx_q: the first index of its configuration ``[x, y, z, qx, qy, qz, qw]``.
        mass: [kg]. placement: its initial world placement.
        geometries: contact geometry, ``(coal shape, placement in the object frame)`` pairs (a URDF's
            ``<collision>`` elements; none: nothing can touch the object).
        visuals: geometry objects for the viewer, attached to the object's joint.
    """

    name: str
    shape: str
    joint: int
    frame: int
    mass: float
    placement: pin.SE3
    geometries: list[tuple[coal.CollisionGeometry, pin.SE3]]
    visuals: list[pin.GeometryObject]
    idx_q: int


def _positive(entry: dict[str, Any], key: str, dimension: str, where: str) -> float:
    value = quantity(entry[key], dimension, f"{where}.{key}")
    if not value > 0:
        raise SceneError(f"{where}.{key} must be > 0, got {entry[key]!r}")
    return within_ceiling(value, f"{where}.{key}", SI_UNITS[dimension], "(0")


def _dimension(value: float, where: str) -> float:
    """An object's dimension (a radius, length or side) [m] when at least :data:`~pinstab.units.MIN_LENGTH`.

    Raises:
        SceneError: naming ``where``, the value and the allowed range.
    """
    if not value >= MIN_LENGTH:
        raise SceneError(
            f"{where} = {value:.3g} m is outside the allowed range [{MIN_LENGTH:g}, {MAX_MAGNITUDE:.0e}] m: "
            f"{MIN_LENGTH_REASON}"
        )
    return value


@np.errstate(over="ignore")  # sizes too large give an infinite inertia, refused by the caller
def _shape(entry: dict[str, Any], where: str) -> tuple[coal.CollisionGeometry, float, np.ndarray]:
    """(coal shape, volume [m^3], unit-mass inertia diagonal [m^2]) of a box, sphere or cylinder."""
    shape = entry["shape"]
    required = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length")}[shape]
    for key in required:
        if key not in entry:
            raise SceneError(f"{where}: a {shape} needs {' and '.join(repr(k) for k in required)}")
    extra = sorted({"size", "radius", "length"} - set(required) & set(entry))
    if extra:
        raise SceneError(f"{where}: {extra[0]!r} does not describe a {shape}; it takes {', '.join(required)}")
    if shape == "box":
        size = vector(entry["size"], 3, f"{where}.size", "length")
        if not np.all(size > 0):
            raise SceneError(f"{where}.size must be three lengths > 0, got {entry['size']!r}")
        within_ceiling(float(size.max()), f"{where}.size", "m", "(0")
        for axis, side in enumerate(size):
            _dimension(float(side), f"{where}.size[{axis}]")
        x, y, z = size**2
        return coal.Box(*size), float(np.prod(size)), np.array([y + z, x + z, x + y]) / 12.0
    radius = _dimension(_positive(entry, "radius", "length", where), f"{where}.radius")
    if shape == "sphere":
        return coal.Sphere(radius), 4.0 / 3.0 * math.pi * radius**3, np.full(3, 0.4 * radius**2)
    length = _dimension(_positive(entry, "length", "length", where), f"{where}.length")
    transverse = (3.0 * radius**2 + length**2) / 12.0
    return (
        coal.Cylinder(radius, length),
        math.pi * radius**2 * length,
        np.array([transverse, transverse, 0.5 * radius**2]),
    )


def _shape_inertia(entry: dict[str, Any], volume: float, unit_inertia: np.ndarray, where: str) -> pin.Inertia:
    if ("density" in entry) == ("mass" in entry):
        raise SceneError(f"{where}: give exactly one of 'density' [kg/m^3] or 'mass' [kg]")
    if "density" in entry:
        if "inertia" in entry:
            raise SceneError(f"{where}: 'inertia' goes with 'mass'; with 'density' it follows from the shape")
        mass = _positive(entry, "density", "density", where) * volume
        return _inertia(mass, np.diag(mass * unit_inertia), where)
    mass = _positive(entry, "mass", "mass", where)
    if "inertia" not in entry:
        return _inertia(mass, np.diag(mass * unit_inertia), where)
    ixx, iyy, izz, ixy, ixz, iyz = vector(entry["inertia"], 6, f"{where}.inertia", None)
    matrix = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    eigenvalues = np.linalg.eigvalsh(matrix)
    if eigenvalues[0] <= 0 or eigenvalues[2] > eigenvalues[0] + eigenvalues[1] + 1e-12 * eigenvalues[2]:
        raise SceneError(
            f"{where}.inertia is not a rigid body's: principal moments {np.round(eigenvalues, 12).tolist()} must be "
            "positive and each at most the sum of the other two"
        )
    floor = mass * MIN_LENGTH**2 / 6.0  # [kg m^2] a cube of side MIN_LENGTH's moments
    if eigenvalues[0] < floor:
        raise SceneError(
            f"{where}.inertia: its smallest principal moment {eigenvalues[0]:.3g} kg m^2 is below {floor:.3g} kg m^2, "
            f"the moment of a cube of its mass ({mass:.3g} kg) and side {MIN_LENGTH:g} m: {MIN_LENGTH_REASON}"
        )
    return _inertia(mass, matrix, where)


def _check_mass(mass: float, where: str) -> None:
    """Refuse an object's mass [kg] below :data:`~pinstab.units.MIN_MASS` (given, or a density times a volume)."""
    if not mass >= MIN_MASS:
        raise SceneError(
            f"{where}.mass = {mass:.3g} kg is outside the allowed range [{MIN_MASS:g}, {MAX_MAGNITUDE:.0e}] kg "
            f"(given, or its density times its volume): {MIN_MASS_REASON}"
        )


def _inertia(mass: float, matrix: np.ndarray, where: str) -> pin.Inertia:
    """The body inertia about the object's centre; refused when the mass [kg] is below
    :data:`~pinstab.units.MIN_MASS` or the mass or the inertia [kg m^2] is beyond
    :data:`~pinstab.units.MAX_MAGNITUDE` (a size, mass or density too large)."""
    _check_mass(mass, where)
    if not (mass <= MAX_MAGNITUDE and np.all(np.abs(matrix) <= MAX_MAGNITUDE)):
        raise SceneError(
            f"{where}: its mass ({mass:.3g} kg) or inertia (largest moment {np.abs(matrix).max():.3g} kg m^2) is "
            f"beyond {MAX_MAGNITUDE:.0e}: the size, mass or density is too large"
        )
    return pin.Inertia(mass, np.zeros(3), matrix)


def _color(entry: dict[str, Any], where: str) -> np.ndarray:
    color = vector(entry.get("color", list(DEFAULT_COLOR)), 4, f"{where}.color", None)
    if np.any(color < 0) or np.any(color > 1):
        raise SceneError(f"{where}.color must be four numbers in [0, 1] (RGBA), got {entry['color']!r}")
    return color


def _urdf_body(entry: dict[str, Any], read_urdf: UrdfReader, where: str):
    """(inertia, [(collision shape, placement)], [visual GeometryObject]) of a one-body URDF."""
    if "urdf" not in entry:
        raise SceneError(f"{where}: a 'urdf' object needs 'urdf', the path of its URDF file")
    body, collision, visual = read_urdf(entry["urdf"], f"{where}.urdf")
    if body.njoints > 1:
        raise SceneError(
            f"{where}.urdf: an object is one rigid body, but joint {body.names[1]!r} of {entry['urdf']} moves; "
            "make every joint fixed"
        )
    if body.inertias[0].mass <= 0:
        raise SceneError(f"{where}.urdf: the links of {entry['urdf']} have no mass")
    _check_mass(body.inertias[0].mass, where)
    shapes = [(g.geometry, g.placement) for g in collision.geometryObjects]
    return body.inertias[0], shapes, list(visual.geometryObjects)


def _placement(entry: dict[str, Any], where: str) -> pin.SE3:
    """The object frame's world placement from ``position`` [m] and ``rpy`` [rad] (zero by default), each
    coordinate within :data:`~pinstab.units.MAX_COORDINATE`, as the joint coordinates of ``initial.q``."""
    frame = placement(entry, "position", "rpy", where)
    coordinates(frame.translation, f"{where}.position", "m")
    return frame


def add_objects(model: pin.Model, value: Any, read_urdf: UrdfReader) -> list[SceneObject]:
    """Add every ``[[objects]]`` entry to ``model`` as a free-flyer body (after the robot's joints, so
    the joint order stays depth-first); the objects, in order. ``read_urdf`` reads a ``urdf`` object's file (the
    scene's URDF reader, :func:`pinstab.readers.urdf.read_body`, which holds it to a robot file's checks)."""
    objects: list[SceneObject] = []
    for index, entry in enumerate(list_of_tables(value, "objects")):
        where = f"objects[{index}]"
        name = entry.get("name")
        if not isinstance(name, str) or not name:
            raise SceneError(f"{where}.name must be a non-empty string, got {name!r}")
        where = f"object {name!r}"
        if model.existJointName(name) or model.existFrame(name) or name == "world":
            raise SceneError(f"{where}: the name is already used by a joint or frame of the model")
        shape = entry.get("shape")
        if shape not in SHAPES:
            raise SceneError(f"{where}: unknown shape {shape!r}; shapes: {choices(SHAPES)}")
        check_keys(entry, URDF_OBJECT_KEYS if shape == "urdf" else OBJECT_KEYS, where)
        color = _color(entry, where)
        if shape == "urdf":
            inertia, geometries, visuals = _urdf_body(entry, read_urdf, where)
        else:
            geometry, volume, unit_inertia = _shape(entry, where)
            inertia = _shape_inertia(entry, volume, unit_inertia, where)
            geometries = [(geometry, pin.SE3.Identity())]
            visuals = [pin.GeometryObject(f"{name}/shape", 0, 0, pin.SE3.Identity(), geometry)]
        joint = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), name)
        model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
        frame = model.addBodyFrame(name, joint, pin.SE3.Identity(), 0)
        for visual in visuals:
            visual.parentJoint, visual.parentFrame = joint, frame
            if shape != "urdf" or not visual.overrideMaterial:
                visual.meshColor = color
        objects.append(
            SceneObject(
                name=name,
                shape=shape,
                joint=joint,
                frame=frame,
                mass=float(inertia.mass),
                placement=_placement(entry, where),
                geometries=geometries,
                visuals=visuals,
                idx_q=model.joints[joint].idx_q,
            )
        )
    return objects


def place_objects(objects: list[SceneObject], q: np.ndarray, declared: set[str]) -> None:
    """Write each object's ``position`` / ``rpy`` into the configuration ``q`` (in place), except for
    objects whose configuration ``initial.q`` declares (``declared``)."""
    for item in objects:
        if item.name not in declared:
            q[item.idx_q : item.idx_q + 7] = pin.SE3ToXYZQUAT(item.placement)


class Nearest(NamedTuple):
    """The object's shape nearest to a fingertip sphere.

    Attributes:
        distance: the gap [m] (< 0: overlap). point: the nearest point on the shape (world) [m].
        normal: unit normal from the fingertip into the object (world). shape: the coal shape.
        local: its placement in the object frame.
    """

    distance: float
    point: np.ndarray
    normal: np.ndarray
    shape: coal.CollisionGeometry
    local: pin.SE3


def nearest_shape(sphere: coal.Sphere, centre: np.ndarray, item: Any, object_placement: pin.SE3) -> Nearest:
    """The nearest of the object's shapes to ``sphere`` centred at ``centre`` (world) [m]."""
    best = None
    for shape, local in item.geometries:
        placed = object_placement * local
        result = coal.DistanceResult()
        distance = coal.distance(
            sphere,
            coal.Transform3s(np.eye(3), centre),
            shape,
            coal.Transform3s(placed.rotation, placed.translation),
            coal.DistanceRequest(),
            result,
        )
        if best is None or distance < best.distance:
            best = Nearest(float(distance), np.array(result.getNearestPoint2()), np.array(result.normal), shape, local)
    return best
