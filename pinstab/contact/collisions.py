"""Hand-object collision checks with coal (Pinocchio's collision library), each a warning, never an error.

* Interpenetration: every shape of the robot's collision geometry (its reader's, reduced like the scene's
  model) against every collision shape of the scene's objects: ``pin.computeCollisions`` finds the pairs that
  touch, coal's signed distance gives their depth (exact for convex shapes; a mesh's per triangle). A pair
  deeper than :data:`PENETRATION_TOLERANCE` is a :class:`~pinstab.errors.PenetrationWarning` naming the link,
  the object and the depth [mm]: at the start
  (when the scene loads) and, at the kept samples of a run (at most :data:`MAX_RUN_SAMPLES` of them, evenly
  spaced), when a pair goes deeper than the tolerance and deeper than it started. Robot links are not checked
  against each other, and a body carrying a fingertip contact on an object is not checked against that object:
  the contact's sphere models that touch (its own shapes overlap the object where the sphere touches it).
* Edge contacts: a sticking fingertip contact whose point lies within :data:`EDGE_TOLERANCE` of an edge or a
  vertex of the object's geometry, where the surface normal is not unique, is an
  :class:`~pinstab.errors.EdgeContactWarning` naming the contact. The test probes the surface from points
  :data:`EDGE_TOLERANCE` above the contact and as far aside in 8 directions: on a face every probe's nearest
  point has the contact's normal; near an edge or a vertex some probe's normal turns by more than
  :data:`EDGE_ANGLE` (about 35 degrees or more at an edge of a box; a curved surface of radius R turns it by
  EDGE_TOLERANCE / R only).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from ..errors import EdgeContactWarning, PenetrationWarning
from .objects import nearest_shape

PENETRATION_TOLERANCE = 1e-4  # [m] an overlap deeper than this is a warning
EDGE_TOLERANCE = 1e-4  # [m] a contact this close to an edge or a vertex sits on it
EDGE_ANGLE = 0.2  # [rad] a probe's normal turned by more than this: the surface has an edge there
PROBES = 8  # directions around the normal
POINT = coal.Sphere(0.0)  # a probe
MAX_RUN_SAMPLES = 500  # kept samples of a run checked at most (evenly spaced, the first and last among them)


class Touch(NamedTuple):
    """A fingertip contact on an object, as the collision checks see it.

    Attributes:
        name: the contact's name. finger_frame: a frame on the finger's body. object_frame: a frame on the
        object's body. at_point: ``object_frame`` sits at the contact point with its z axis the normal into the
        object (a sticking contact; a rolling contact's point moves and is checked on a face when it loads).
    """

    name: str
    finger_frame: int
    object_frame: int
    at_point: bool


class Overlap(NamedTuple):
    """A robot shape and an object shape overlapping: link and shape names, object name, depth [m] (> 0)."""

    link: str
    shape: str
    item: str
    depth: float

    def described(self) -> str:
        """'link 'L' (shape 'S') and object 'O' interpenetrate by D mm'."""
        return (
            f"link {self.link!r} (collision shape {self.shape!r}) and object {self.item!r} interpenetrate by "
            f"{self.depth * 1e3:.3f} mm"
        )


class CollisionCheck:
    """The robot-object pairs of a scene and their signed distances at a configuration.

    Args:
        model: the scene's model (the objects' free-flyers included). robot: the robot's collision geometry,
            its indices those of ``model``. objects: the scene objects (:class:`~pinstab.contact.objects.SceneObject`).
        touches: the scene's fingertip contacts; their finger bodies are not checked against their objects.
        tolerance: the depth [m] beyond which an overlap is reported.
    """

    def __init__(
        self,
        model: pin.Model,
        robot: pin.GeometryModel,
        objects: Sequence[Any],
        touches: Sequence[Touch] = (),
        tolerance: float = PENETRATION_TOLERANCE,
    ) -> None:
        self.model, self.tolerance = model, tolerance
        self.geometry = pin.GeometryModel()
        exempt = {(model.frames[t.finger_frame].parentJoint, model.frames[t.object_frame].parentJoint) for t in touches}
        links = [self.geometry.addGeometryObject(shape) for shape in robot.geometryObjects]
        self.names: list[tuple[str, str, str]] = []  # per pair: link, robot shape, object
        for item in objects:
            for index, (shape, local) in enumerate(item.geometries):
                added = self.geometry.addGeometryObject(
                    pin.GeometryObject(f"{item.name}/collision{index}", item.joint, item.frame, local, shape)
                )
                for link in links:
                    robot_shape = self.geometry.geometryObjects[link]
                    if (robot_shape.parentJoint, item.joint) in exempt:
                        continue
                    self.geometry.addCollisionPair(pin.CollisionPair(link, added))
                    self.names.append((model.frames[robot_shape.parentFrame].name, robot_shape.name, item.name))
        self._data = pin.Data(model)
        self._geometry_data = self.geometry.createData()

    def depths(self, q: np.ndarray) -> np.ndarray:
        """The overlap depth [m] of every pair at configuration q: minus the signed distance of the pairs that touch
        or overlap (coal's collision test, then its distance for those only: a mesh's distance costs milliseconds),
        0 for the others."""
        depths = np.zeros(len(self.names))
        if not self.names:
            return depths
        geometry, data = self.geometry, self._geometry_data
        pin.computeCollisions(self.model, self._data, geometry, data, q, False)
        for pair, result in enumerate(data.collisionResults):
            if result.isCollision():
                depths[pair] = -pin.computeDistance(geometry, data, pair).min_distance
        return depths

    def overlaps(self, q: np.ndarray) -> list[Overlap]:
        """The pairs overlapping deeper than the tolerance at q, deepest first."""
        depths = self.depths(q)
        found = [Overlap(*self.names[k], float(depths[k])) for k in np.flatnonzero(depths > self.tolerance)]
        return sorted(found, key=lambda overlap: -overlap.depth)

    def warn_at_start(self, q: np.ndarray, scene: str) -> list[Overlap]:
        """A :class:`~pinstab.errors.PenetrationWarning` per pair overlapping beyond the tolerance at q; those
        pairs."""
        found = self.overlaps(q)
        for overlap in found:
            warnings.warn(
                PenetrationWarning(
                    f"scene {scene}: {overlap.described()} at the start (tolerance {self.tolerance * 1e3:g} mm)"
                ),
                stacklevel=3,
            )
        return found

    def warn_during(self, t: np.ndarray, q: np.ndarray, scene: str) -> list[Overlap]:
        """A :class:`~pinstab.errors.PenetrationWarning` per pair that, at the kept samples (t [s], q), overlaps
        deeper than the tolerance and deeper than at the first sample by more than the tolerance; those pairs at
        their deepest."""
        if not self.names or len(t) < 2:
            return []
        picked = np.unique(np.linspace(0, len(t) - 1, min(len(t), MAX_RUN_SAMPLES)).round().astype(int))
        depths = np.array([self.depths(q[k]) for k in picked])
        deepest = np.argmax(depths, axis=0)
        found = []
        for pair in range(len(self.names)):
            depth, start = float(depths[deepest[pair], pair]), float(depths[0, pair])
            if depth > self.tolerance and depth > max(start, 0.0) + self.tolerance:
                overlap = Overlap(*self.names[pair], depth)
                found.append(overlap)
                warnings.warn(
                    PenetrationWarning(
                        f"scene {scene}: {overlap.described()} during the run (deepest at t = "
                        f"{t[picked[deepest[pair]]]:.4g} s; {max(start, 0.0) * 1e3:.3f} mm at the start; tolerance "
                        f"{self.tolerance * 1e3:g} mm)"
                    ),
                    stacklevel=3,
                )
        return found


def edge_contacts(
    model: pin.Model, q: np.ndarray, objects: Sequence[Any], touches: Sequence[Touch], scene: str
) -> list[str]:
    """An :class:`~pinstab.errors.EdgeContactWarning` per sticking fingertip contact that sits on an edge or a
    vertex of its object's geometry at configuration q (the module's probe test); their names."""
    data = pin.Data(model)
    pin.framesForwardKinematics(model, data, q)
    by_joint = {item.joint: item for item in objects}
    found = []
    for touch in touches:
        item = by_joint.get(model.frames[touch.object_frame].parentJoint)
        if not touch.at_point or item is None:
            continue
        contact = data.oMf[touch.object_frame]
        turn = normal_turn(item, data.oMf[item.frame], contact.translation, contact.rotation[:, 2])
        if turn > EDGE_ANGLE:
            found.append(touch.name)
            warnings.warn(
                EdgeContactWarning(
                    f"scene {scene}: contact {touch.name!r} sits on an edge or a vertex of object {item.name!r} "
                    f"(within {EDGE_TOLERANCE * 1e3:g} mm: the surface normal turns by {np.degrees(turn):.0f} deg "
                    "there), where its normal is not unique; place the fingertip on a face"
                ),
                stacklevel=3,
            )
    return found


def normal_turn(item: Any, placement: pin.SE3, point: np.ndarray, inward: np.ndarray) -> float:
    """The largest angle [rad] between ``inward`` (the contact's normal into the object) and the normals of the
    object's surface seen from probes :data:`EDGE_TOLERANCE` above ``point`` (world) [m] and as far aside."""
    outward = -inward / np.linalg.norm(inward)
    tangent = np.cross(outward, np.eye(3)[int(np.argmin(np.abs(outward)))])
    tangent /= np.linalg.norm(tangent)
    bitangent = np.cross(outward, tangent)
    turn = 0.0
    for angle in np.arange(PROBES) * 2.0 * np.pi / PROBES:
        probe = point + EDGE_TOLERANCE * (outward + np.cos(angle) * tangent + np.sin(angle) * bitangent)
        normal = nearest_shape(POINT, probe, item, placement).normal
        turn = max(turn, float(np.arccos(np.clip(normal @ -outward, -1.0, 1.0))))
    return turn
