"""Contacts found from collision geometry with coal (Pinocchio's collision library).

The shapes are the robot's collision geometry, the scene objects' collision shapes and the ground, a coal
half-space (``{x : n . (x - p0) <= 0}``, fixed in the world). A *pair* is two shapes allowed to touch: by default
every shape against every other except two shapes of one body and the shapes of two bodies joined by a joint
(adjacent links). For each pair, after a broad phase (the shapes' bounding spheres farther apart than the margin:
no contact), coal's signed distance gives the nearest points and the normal; the pair's contact *features* are
then the points of shape A that lie within the margin of the nearest one, measured across the separating plane
(B's tangent plane at its nearest point, normal along coal's; when B is a box, the face of B that normal is
nearest to, exactly: coal's normal and point between two boxes face to face are its solver's, 1e-12 off): a
sphere's centre with its radius (one feature), a capsule's two end centres with its radius, a box's eight
corners, a convex mesh's vertices, and a cylinder's features by how it lies: on its
side (its axis within :data:`SIDE_TILT` of the plane) the two ends of its lowest line, each the centre of an
end cap with the cylinder's radius (a sphere there touches the plane where the rim does: exact while the axis
stays parallel to the plane, rolling or at rest); else its rim points, :data:`RIM_POINTS` around each end cap
(a cap flat on the plane rests on them; a cylinder tilted onto its rim touches it at the nearest of them, a
polygon's corner, not the circle's lowest point). Two round shapes pair only as a sphere (shape A) against a sphere
or a capsule (:mod:`~pinstab.contact.round_pairs`): one feature, the sphere's centre, on the plane normal to the line
from B's core, which the contacts re-compute at every state (:attr:`ContactShapes.cores`).

The numbers are compiled (:class:`~pinstab.kernels.GeometryFeatures`, ``cpp/geometry_features.cpp``, the only place
these rules are): the placements, the broad phase, coal's signed distance, a box's face, the gaps (a cylinder's by how
it lies) and the margin filter; round pairs pass its broad phase and are measured here, their plane from
:func:`~pinstab.contact.round_pairs.core_nearest`, the rule the dynamics re-compute it with at every state.

A feature keeps its identity while it persists: its name is ``<shapeA>/<shapeB>[k]``, k its index among shape A's
points (a box's corner k is the same corner wherever the box turns), and the features come in the order of the
pairs, then of k. Each becomes a point contact the contact machinery already treats
(:class:`~pinstab.constraints.contacts.PointContact`): the point on body A (a sphere of the feature's radius
centred there) on the separating plane, fixed in the world for the ground, carried by body B otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from ..errors import SceneError, choices
from ..kernels import GeometryFeatures
from .round_pairs import core_nearest

GROUND = "ground"  # the ground's shape name
MARGIN = 0.1  # [-] the default margin, in bounding radii of shape A: features this close to the nearest one count
SHAPE_KINDS = ("box", "capsule", "convex", "cylinder", "sphere")  # the shapes whose features are found
RIM_POINTS = 8  # a cylinder's points around each end cap's rim
SIDE_TILT = 1e-6  # [rad] a cylinder whose axis is this close to parallel to the plane lies on its side


class Feature(NamedTuple):
    """A contact feature of a pair at a configuration.

    Attributes:
        name: ``<shapeA>/<shapeB>[k]``. pair: the pair's index. index: k, the point's index on shape A.
        joint_point: the point on body A [m] in its joint's frame. world: the point [m, world]. radius: the
        sphere's radius at it [m] (0: a vertex). normal: the separating plane's unit normal into A (world).
        point: a point of the plane [m, world]. gap: the feature's signed distance to the plane [m] (< 0: overlap).
    """

    name: str
    pair: int
    index: int
    joint_point: np.ndarray
    world: np.ndarray
    radius: float
    normal: np.ndarray
    point: np.ndarray
    gap: float


class FoundFeatures(NamedTuple):
    """What the compiled finder (:class:`~pinstab.kernels.GeometryFeatures`) found at a configuration, before the
    :class:`Feature` tuples are made from it (:meth:`ContactShapes.features_of`).

    Attributes:
        pairs, indices: each feature's pair and point index k. gaps: [m]. normals (n, 3), points (n, 3) [m]: their
        planes (world). worlds (n, 3): the points [m, world]. rounds: the round pairs kept, measured in Python.
    """

    pairs: np.ndarray
    indices: np.ndarray
    gaps: np.ndarray
    normals: np.ndarray
    points: np.ndarray
    worlds: np.ndarray
    rounds: list[int]

    def key(self) -> tuple[bytes, bytes, tuple[int, ...]]:
        """Which features were found, in their order: two finds with one key found the same features (names)."""
        return self.pairs.tobytes(), self.indices.tobytes(), tuple(self.rounds)


def shape_points(shape: coal.CollisionGeometry, where: str) -> tuple[np.ndarray, np.ndarray]:
    """The points (k, 3) [m, shape frame] of a shape's features and the radius (k,) [m] of each (0: a vertex).
    A cylinder's: the centres of its end caps (+z, -z), then :data:`RIM_POINTS` around the +z cap's rim from +x
    counter-clockwise, then as many around the -z cap's.

    Raises:
        SceneError: a shape kind without features here (naming the kinds there are).
    """
    if isinstance(shape, coal.Sphere):
        return np.zeros((1, 3)), np.full(1, float(shape.radius))
    if isinstance(shape, coal.Capsule):
        ends = np.array([[0.0, 0.0, shape.halfLength], [0.0, 0.0, -shape.halfLength]])
        return ends, np.full(2, float(shape.radius))
    if isinstance(shape, coal.Cylinder):
        radius, half = float(shape.radius), float(shape.halfLength)
        turns = 2.0 * np.pi * np.arange(RIM_POINTS) / RIM_POINTS
        rim = np.column_stack([radius * np.cos(turns), radius * np.sin(turns), np.zeros(RIM_POINTS)])
        ends = np.array([[0.0, 0.0, half], [0.0, 0.0, -half]])
        points = np.vstack([ends, rim + ends[0], rim + ends[1]])
        return points, np.concatenate([np.full(2, radius), np.zeros(2 * RIM_POINTS)])
    if isinstance(shape, coal.Box):
        signs = np.array([[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)], dtype=float)
        return signs * np.asarray(shape.halfSide), np.zeros(8)
    if isinstance(shape, coal.ConvexBase):
        points = np.array([np.asarray(p) for p in shape.points()])
        return points, np.zeros(len(points))
    raise SceneError(
        f"{where}: a {type(shape).__name__} shape has no contact features here; shapes with them: "
        f"{', '.join(SHAPE_KINDS)} (a mesh: give its convex hull)"
    )


def is_round(shape: coal.CollisionGeometry) -> bool:
    """Whether a shape touches a plane with round features (a sphere, a capsule, a cylinder on its side): such a
    shape pairs with a shape whose plane it touches (a box, a convex mesh, the ground); of two round shapes only a
    sphere with a sphere or a capsule pair (:mod:`~pinstab.contact.round_pairs`)."""
    return isinstance(shape, coal.Sphere | coal.Capsule | coal.Cylinder)


def core_ends(shape: coal.CollisionGeometry) -> np.ndarray | None:
    """The ends (2, 3) [m, shape frame] of a sphere's or a capsule's core (a sphere's centre twice, a capsule's end
    centres), the B side of a round pair; None for other shapes."""
    if isinstance(shape, coal.Sphere):
        return np.zeros((2, 3))
    if isinstance(shape, coal.Capsule):
        return shape_points(shape, "")[0]
    return None


class ContactShapes:
    """The collision shapes of a scene, the pairs allowed to touch and their contact features.

    Args:
        model: the scene's model. robot: the robot's collision geometry (indices of ``model``).
        objects: the scene objects (:class:`~pinstab.contact.objects.SceneObject`).
        grounds: (unit normal, point [m]) of each ground plane (none: no ground): the first named :data:`GROUND`,
            the k-th after it ``ground_k`` (half-spaces whose union is the ground: planes tilted inward, a pocket).
    """

    def __init__(
        self,
        model: pin.Model,
        robot: pin.GeometryModel,
        objects: Sequence[Any],
        grounds: Sequence[tuple[np.ndarray, np.ndarray]],
    ) -> None:
        self.model = model
        self.geometry = pin.GeometryModel()
        for shape in robot.geometryObjects:
            self.geometry.addGeometryObject(shape)
        for item in objects:
            for index, (shape, local) in enumerate(item.geometries):
                self.geometry.addGeometryObject(
                    pin.GeometryObject(f"{item.name}/collision{index}", item.joint, item.frame, local, shape)
                )
        for k, (normal, point) in enumerate(grounds):
            name = GROUND if k == 0 else f"{GROUND}_{k}"
            self.geometry.addGeometryObject(
                pin.GeometryObject(name, 0, 0, pin.SE3.Identity(), coal.Halfspace(normal, float(normal @ point)))
            )
        self.names = [shape.name for shape in self.geometry.geometryObjects]
        self.pairs: list[tuple[int, int]] = []
        self.margins: list[float] = []
        self.cores: list[np.ndarray | None] = []  # per pair: B's core ends (2, 3) [m, B's shape frame] (a round pair)
        self._points: list[tuple[np.ndarray, np.ndarray]] = []
        # per pair, per point of shape A: its feature's name, its place [m] in A's joint's frame, its radius [m]
        self._named: list[list[tuple[str, np.ndarray, float]]] = []
        self._finder = GeometryFeatures([], [], [], [], [], np.sin(SIDE_TILT))
        self._data = pin.Data(model)
        self._geometry_data = self.geometry.createData()

    def shape(self, name: Any, where: str) -> int:
        """A shape's index by name.

        Raises:
            SceneError: an unknown name, listing the shapes.
        """
        if not isinstance(name, str) or name not in self.names:
            raise SceneError(f"{where}: no collision shape {name!r}; shapes: {choices(self.names)}")
        return self.names.index(name)

    def default_pairs(self) -> list[tuple[int, int]]:
        """Every two shapes but two of one body and those of two bodies a joint joins (adjacent links), in
        shape order; the ground (and any shape on the world) last in a pair."""
        joints = [shape.parentJoint for shape in self.geometry.geometryObjects]
        found = []
        for a in range(len(joints)):
            for b in range(a + 1, len(joints)):
                ja, jb = joints[a], joints[b]
                if ja == jb or self._joined(ja, jb) or self._joined(jb, ja):
                    continue
                found.append((b, a) if ja == 0 else (a, b))
        return found

    def _joined(self, child: int, parent: int) -> bool:
        """Whether joint ``child`` joins its body to ``parent``'s (a free flyer joins none: it is no hinge)."""
        joint = self.model.joints[child]
        return self.model.parents[child] == parent and joint.shortname() != "JointModelFreeFlyer"

    def allow(self, a: int, b: int, margin: float | None, where: str) -> None:
        """Allow the pair (shape a, shape b); features within ``margin`` [m] of the nearest one count (None:
        :data:`MARGIN` bounding radii of a). A shape whose features cannot be found (a half-space) is put second, a
        round one (:func:`is_round`) first.

        Raises:
            SceneError: two shapes of one body, or neither shape with features (naming them).
        """
        objects = self.geometry.geometryObjects
        if objects[a].parentJoint == objects[b].parentJoint:
            raise SceneError(f"{where}: shapes {self.names[a]!r} and {self.names[b]!r} are on one body")
        core = None
        if is_round(objects[a].geometry) and is_round(objects[b].geometry):
            if not isinstance(objects[a].geometry, coal.Sphere):
                a, b = b, a  # a sphere is shape A of a round pair: its centre against B's core
            core = core_ends(objects[b].geometry)
            if not isinstance(objects[a].geometry, coal.Sphere) or core is None:
                raise SceneError(
                    f"{where}: shapes {self.names[a]!r} and {self.names[b]!r} are both round: of two round shapes a "
                    "sphere pairs with a sphere or a capsule (not yet a capsule with a capsule, nor a cylinder with a "
                    "round shape); pair the other with a box or a convex shape"
                )
        elif isinstance(objects[a].geometry, coal.Halfspace) or is_round(objects[b].geometry):
            a, b = b, a  # a round shape's features touch the other's plane (a ball on a box's face: its lowest point)
        points = shape_points(objects[a].geometry, f"{where}: shape {self.names[a]!r}")
        for shape in (a, b):  # the broad phase's bounding spheres (coal leaves a shape's unset until asked)
            if not isinstance(objects[shape].geometry, coal.Halfspace):
                objects[shape].geometry.computeLocalAABB()
        radius = float(np.max(points[1] + np.linalg.norm(points[0], axis=1)))
        self.pairs.append((a, b))
        self.cores.append(core)
        self.margins.append(MARGIN * max(radius, np.finfo(float).tiny) if margin is None else margin)
        self._points.append(points)
        label, joint = self.label(len(self.pairs) - 1), self.joint_points(len(self.pairs) - 1)
        self._named.append([(f"{label}[{k}]", joint[:, k], float(r)) for k, r in enumerate(points[1])])
        self._finder = GeometryFeatures(
            self.pairs,
            [points for points, _ in self._points],
            [radii for _, radii in self._points],
            self.margins,
            [core is not None for core in self.cores],
            np.sin(SIDE_TILT),
        )

    def features(self, q: np.ndarray) -> list[Feature]:
        """The contact features of every allowed pair at configuration q, in pair order, then by point."""
        return self.features_of(self.find(q))

    def find(self, q: np.ndarray, pair: int = -1) -> FoundFeatures:
        """What the compiled finder finds at configuration q: the features of every pair that the broad phase and the
        margins keep (pair -1), or every point of one pair; the placements are left at q (:meth:`features_of`)."""
        found = self._finder.find(
            self.model, self._data, self.geometry, self._geometry_data, np.asarray(q, dtype=float), pair
        )
        return FoundFeatures(*found)

    def features_of(self, found: FoundFeatures) -> list[Feature]:
        """The features of the last :meth:`find` (``found``), in pair order, then by point."""
        places = found.pairs.tolist(), found.indices.tolist()
        rows = zip(*places, found.worlds, found.normals, found.points, found.gaps, strict=True)
        features = [self._feature(*row) for row in rows]
        if not found.rounds:
            return features
        return sorted(features + [self._round_feature(p) for p in found.rounds], key=lambda feature: feature.pair)

    def label(self, pair: int) -> str:
        """``<shapeA>/<shapeB>``: a pair's name."""
        a, b = self.pairs[pair]
        return f"{self.names[a]}/{self.names[b]}"

    def joint_points(self, pair: int) -> np.ndarray:
        """The feature points (k, 3) of a pair's shape A [m] in its joint's frame."""
        local = self.geometry.geometryObjects[self.pairs[pair][0]].placement
        return local.rotation @ self._points[pair][0].T + local.translation[:, None]

    def frame_placement(self, frame: int) -> pin.SE3:
        """A frame's world placement at the configuration :meth:`features` last took."""
        return pin.updateFramePlacement(self.model, self._data, frame).copy()

    def pair_features(self, q: np.ndarray, pair: int) -> list[Feature]:
        """Every feature point of one pair at configuration q, found or not (no broad phase, no margin): where a
        contact found at another configuration is made, its plane that of q."""
        return self.features_of(self.find(q, pair))

    def _round_feature(self, pair: int) -> Feature:
        """A round pair's feature, its sphere's centre, at the placements last updated: its plane on the line from
        B's core (:mod:`~pinstab.contact.round_pairs`)."""
        placed_a = self._geometry_data.oMg[self.pairs[pair][0]]
        shape_b = self.geometry.geometryObjects[self.pairs[pair][1]].geometry
        points, radii = self._points[pair]
        centre = placed_a.translation
        nearest = core_nearest(centre, self.core_world(pair))[0]
        normal = (centre - nearest) / np.linalg.norm(centre - nearest)
        plane_point = nearest + float(shape_b.radius) * normal
        world = placed_a.rotation @ points.T + placed_a.translation[:, None]
        gaps = normal @ (world - plane_point[:, None]) - radii
        return self._feature(pair, 0, world[:, 0], normal, plane_point, gaps[0])

    def _feature(
        self, pair: int, k: int, world: np.ndarray, normal: np.ndarray, point: np.ndarray, gap: float
    ) -> Feature:
        """Point k of a pair's shape A as a feature at world place ``world`` [m], its gap ``gap`` [m] to the plane
        (unit ``normal`` into A, through ``point`` [m, world])."""
        name, joint, radius = self._named[pair][k]
        return Feature(name, pair, k, joint, world, radius, normal, point, gap)

    def core_world(self, pair: int) -> np.ndarray:
        """A round pair's B core ends (2, 3) [m, world] at the placements last updated."""
        placed = self._geometry_data.oMg[self.pairs[pair][1]]
        return (placed.rotation @ self.cores[pair].T).T + placed.translation
