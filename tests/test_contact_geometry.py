"""The compiled contact features of collision-shape pairs (pinstab.contact.geometry, cpp/geometry_features.cpp)
against a second implementation here, in NumPy on coal's Python bindings (the rules the module docstring states:
the broad phase on bounding spheres, coal's signed distance, a box B's face, shape A's points' gaps to the
separating plane, a cylinder's points by how it lies, the margin filter), on states of hand-cube, box-stack,
cylinders on a box and on the ground, and a ball among fixed balls (round pairs), each moved at random about its
start: the same features (names, pairs, points, radii exactly; placements, normals, plane points and gaps to
1e-15, the sums of the two differing in rounding only)."""

from __future__ import annotations

import math

import coal
import numpy as np
import pinocchio as pin
import pytest

from pinstab.contact.geometry import SIDE_TILT, ContactShapes
from pinstab.contact.round_pairs import core_nearest
from pinstab.generators import GROUND_URDF
from pinstab.scene import load_scene, scene_from_dict

TOLERANCE = 1e-15  # [m] (and [-] for unit normals): rounding of sums of a few terms of at most ~1 m
SAMPLES = 40  # random states per scene


def reference(shapes: ContactShapes, q: np.ndarray, only: int | None = None) -> list[tuple]:
    """The features (name, pair, k, joint point, world point, radius, normal, plane point, gap) at q in NumPy: of
    every pair after the broad phase and the margin (only None), else every point of pair ``only``."""
    geometry, objects = shapes.geometry, shapes.geometry.geometryObjects
    data = geometry.createData()
    pin.updateGeometryPlacements(shapes.model, shapes.model.createData(), geometry, data, q)
    found = []
    for pair in range(len(shapes.pairs)) if only is None else [only]:
        a, b = shapes.pairs[pair]
        shape_a, shape_b, placed_a, placed_b = objects[a].geometry, objects[b].geometry, data.oMg[a], data.oMg[b]
        if only is None and not isinstance(shape_b, coal.Halfspace):
            apart = np.linalg.norm(placed_a.act(shape_a.aabb_center) - placed_b.act(shape_b.aabb_center))
            if apart > shape_a.aabb_radius + shape_b.aabb_radius + shapes.margins[pair]:
                continue
        points, radii = shapes._points[pair]
        if shapes.cores[pair] is not None:
            ends = (placed_b.rotation @ shapes.cores[pair].T).T + placed_b.translation
            nearest = core_nearest(placed_a.translation, ends)[0]
            normal = (placed_a.translation - nearest) / np.linalg.norm(placed_a.translation - nearest)
            plane_point = nearest + shape_b.radius * normal
        else:
            normal, plane_point = separating_plane(shape_a, placed_a, shape_b, placed_b)
        world = placed_a.rotation @ points.T + placed_a.translation[:, None]
        gaps = normal @ (world - plane_point[:, None]) - radii
        if isinstance(shape_a, coal.Cylinder):
            side = abs((placed_a.rotation.T @ normal)[2]) <= math.sin(SIDE_TILT)
            gaps[(np.arange(gaps.size) < 2) != side] = np.inf
        joint = shapes.joint_points(pair)
        kept = range(gaps.size) if only is not None else np.flatnonzero(gaps <= gaps.min() + shapes.margins[pair])
        for k in kept:
            name = f"{shapes.label(pair)}[{k}]"
            found.append((name, pair, int(k), joint[:, k], world[:, k], radii[k], normal, plane_point, gaps[k]))
    return found


def separating_plane(shape_a, placed_a: pin.SE3, shape_b, placed_b: pin.SE3) -> tuple[np.ndarray, np.ndarray]:
    """coal's normal (into A) and B's nearest point; a box B's face whose normal is nearest to coal's."""
    result = coal.DistanceResult()
    transforms = [coal.Transform3s(p.rotation, p.translation) for p in (placed_a, placed_b)]
    coal.distance(shape_a, transforms[0], shape_b, transforms[1], coal.DistanceRequest(), result)
    normal = -np.asarray(result.normal)
    if not isinstance(shape_b, coal.Box):
        return normal, np.asarray(result.getNearestPoint2())
    local = placed_b.rotation.T @ normal
    axis = int(np.argmax(np.abs(local)))
    outward = np.zeros(3)
    outward[axis] = 1.0 if local[axis] > 0.0 else -1.0
    return placed_b.rotation @ outward, placed_b.act(outward * np.asarray(shape_b.halfSide))


def assert_same(compiled: list, expected: list[tuple]) -> None:
    assert [f[:3] for f in compiled] == [f[:3] for f in expected]
    for ours, theirs in zip(compiled, expected, strict=True):
        np.testing.assert_array_equal(ours.joint_point, theirs[3])
        assert ours.radius == theirs[5]
        for value, other in ((ours.world, theirs[4]), (ours.normal, theirs[6]), (ours.point, theirs[7])):
            np.testing.assert_allclose(value, other, rtol=0.0, atol=TOLERANCE)
        assert ours.gap == theirs[8] or abs(ours.gap - theirs[8]) <= TOLERANCE  # inf: a point that does not count


def can_objects(rpy: list[float], z: float) -> list[dict]:
    """A cylinder (radius 5 cm, length 20 cm) at height z [m] turned by rpy [rad] on a 30 x 30 x 10 cm box."""
    table = {"name": "table", "shape": "box", "size": [0.3, 0.3, 0.1], "mass": 2.0, "position": [0.0, 0.0, 0.05]}
    can = {"name": "can", "shape": "cylinder", "radius": 0.05, "length": 0.2, "mass": 1.0}
    return [table, can | {"position": [0.0, 0.0, z], "rpy": rpy}]


def balls() -> dict:
    """A ball (radius 0.1 m) on a fixed ball (0.5 m) beside a fixed box, touching the ground."""
    fixed = (
        '<?xml version="1.0"?><robot name="fixed"><link name="base">'
        '<collision><geometry><sphere radius="0.5"/></geometry></collision>'
        '<collision><origin xyz="0.7 0 0.1"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision>'
        "</link></robot>"
    )
    ball = {"name": "ball", "shape": "sphere", "radius": 0.1, "mass": 1.0, "position": [0.06, 0.0, 0.597]}
    return {"robot": {"urdf_text": fixed}, "objects": [ball], "contacts": [{"kind": "geometry", "margin": 0.05}]}


def scenes() -> dict:
    can = {"robot": {"urdf_text": GROUND_URDF}, "contacts": [{"kind": "geometry"}]}
    return {
        "hand-cube": lambda: load_scene("hand-cube"),
        "box-stack": lambda: load_scene("box-stack", drop=0.01),
        "can-standing": lambda: scene_from_dict(can | {"objects": can_objects([0.0, 0.0, 0.0], 0.2)}, name="can"),
        "can-lying": lambda: scene_from_dict(can | {"objects": can_objects([math.pi / 2, 0.0, 0.0], 0.15)}, name="c"),
        "can-tilted": lambda: scene_from_dict(can | {"objects": can_objects([0.4, 0.2, 0.0], 0.25)}, name="can"),
        "balls": lambda: scene_from_dict(balls(), name="balls"),
    }


@pytest.mark.parametrize("name", list(scenes()))
def test_the_compiled_features_are_the_second_implementation_s(name):
    """At the start and at SAMPLES states moved at random about it (0.01 in each velocity coordinate: shapes
    pressed into each other and apart, tilted off their faces): every pair's features after the broad phase and
    the margin, and every point of each pair, as the NumPy implementation finds them."""
    scene = scenes()[name]()
    rng = np.random.default_rng(7)
    found_any = 0
    for finder in scene.contact_finders:
        shapes = finder.shapes
        moves = [np.zeros(scene.model.nv)] + [0.01 * rng.standard_normal(scene.model.nv) for _ in range(SAMPLES)]
        states = [pin.integrate(scene.model, scene.q0, move) for move in moves]
        for q in states:
            features = shapes.features(q)
            assert_same(features, reference(shapes, q))
            found_any += len(features)
            for pair in range(len(shapes.pairs)):
                assert_same(shapes.pair_features(q, pair), reference(shapes, q, pair))
    assert found_any > 0


def test_features_are_the_same_to_the_last_bit_each_time():
    """The features at q, then at another state, then at q again: the same to the last bit."""
    scene = load_scene("hand-cube")
    shapes = scene.contact_finders[-1].shapes
    q = pin.integrate(scene.model, scene.q0, np.full(scene.model.nv, 0.003))
    first = shapes.features(q)
    shapes.features(scene.q0)
    again = shapes.features(q)
    assert [f.name for f in first] == [f.name for f in again] and first
    for ours, theirs in zip(first, again, strict=True):
        for field in ("world", "normal", "point", "gap"):
            np.testing.assert_array_equal(getattr(ours, field), getattr(theirs, field))
