"""Scene objects: mass and inertia against coal's own volume and inertia, free fall against the closed
form, initial placement, refusals."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from conftest import ROBOTS
from pinstab import simulate
from pinstab.errors import SceneError
from pinstab.scene import scene_from_dict

DENSITY = 700.0
SHAPES = {
    "box": ({"size": [0.1, 0.2, 0.3]}, coal.Box(0.1, 0.2, 0.3)),
    "sphere": ({"radius": 0.05}, coal.Sphere(0.05)),
    "cylinder": ({"radius": 0.05, "length": 0.2}, coal.Cylinder(0.05, 0.2)),
}


def object_scene(objects: list[dict], **extra) -> dict:
    """A fixed four-bar robot (any robot will do) plus ``objects``."""
    return {
        "robot": {"urdf": str(ROBOTS / "urdf" / "fourbar.urdf")},
        "objects": objects,
        **extra,
    }


@pytest.mark.parametrize("shape", SHAPES)
def test_mass_and_inertia_from_density_match_coal(shape):
    """m = rho V and I = rho (coal's unit-density inertia about the centre), to 1e-12 relative."""
    keys, reference = SHAPES[shape]
    scene = scene_from_dict(object_scene([{"name": "thing", "shape": shape, "density": DENSITY, **keys}]))
    inertia = scene.model.inertias[scene.objects[0].joint]
    np.testing.assert_allclose(inertia.mass, DENSITY * reference.computeVolume(), rtol=1e-12)
    np.testing.assert_allclose(inertia.inertia, DENSITY * reference.computeMomentofInertia(), rtol=1e-12, atol=1e-15)
    assert np.allclose(inertia.lever, 0.0)


def test_given_mass_and_inertia_are_used():
    scene = scene_from_dict(
        object_scene(
            [
                {
                    "name": "b",
                    "shape": "sphere",
                    "radius": 0.05,
                    "mass": "200 g",
                    "inertia": [1e-4, 2e-4, 2.5e-4, 0, 0, 0],
                }
            ]
        )
    )
    inertia = scene.model.inertias[scene.objects[0].joint]
    assert inertia.mass == pytest.approx(0.2, rel=1e-15)
    np.testing.assert_allclose(np.diag(inertia.inertia), [1e-4, 2e-4, 2.5e-4], rtol=1e-15)


def test_object_starts_where_declared_and_falls_freely():
    """A sphere released at rest falls as z0 - g t^2 / 2 (RK4 is exact on a quadratic: 1e-12 m) and
    keeps its orientation; the model's joint order stays depth-first."""
    rpy = [0.1, -0.2, 0.3]
    scene = scene_from_dict(
        object_scene(
            [
                {
                    "name": "ball",
                    "shape": "sphere",
                    "radius": 0.03,
                    "density": 1000,
                    "position": [0.1, 0.2, 1.0],
                    "rpy": rpy,
                }
            ]
        )
    )
    assert scene.model.check(scene.model.createData())
    start = pin.XYZQUATToSE3(scene.q0[scene.objects[0].idx_q : scene.objects[0].idx_q + 7])
    np.testing.assert_allclose(start.translation, [0.1, 0.2, 1.0], atol=1e-15)
    np.testing.assert_allclose(start.rotation, pin.rpy.rpyToMatrix(np.array(rpy)), atol=1e-15)
    traj = simulate(scene, method="none", integrator="rk4", dt=1e-2, duration=0.5, progress=False)
    index = scene.objects[0].idx_q
    np.testing.assert_allclose(traj.q[:, index + 2], 1.0 - 0.5 * 9.81 * traj.t**2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        traj.q[:, index + 3 : index + 7], np.tile(traj.q[0, index + 3 : index + 7], (len(traj.t), 1)), atol=1e-12
    )


def test_initial_q_overrides_the_object_position():
    scene = scene_from_dict(
        object_scene(
            [{"name": "ball", "shape": "sphere", "radius": 0.03, "density": 1000, "position": [0.1, 0.2, 1.0]}],
            initial={"q": {"ball": [0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 1.0]}},
        )
    )
    assert scene.q0[scene.objects[0].idx_q + 2] == 2.0


@pytest.mark.parametrize(
    ("entry", "pattern"),
    [
        (
            {"name": "x", "shape": "cone", "radius": 1, "density": 1},
            r"object 'x': unknown shape 'cone'; shapes: box, cylinder, sphere, urdf",
        ),
        (
            {"name": "x", "shape": "box", "size": [0.1, -0.1, 0.1], "density": 1},
            r"object 'x'.size must be three lengths > 0",
        ),
        ({"name": "x", "shape": "sphere", "radius": 0, "density": 1}, r"object 'x'.radius must be > 0"),
        (
            {"name": "x", "shape": "sphere", "radius": 0.1},
            r"object 'x': give exactly one of 'density' \[kg/m\^3\] or 'mass'",
        ),
        ({"name": "x", "shape": "sphere", "radius": 0.1, "mass": 1, "density": 1}, r"give exactly one of 'density'"),
        ({"name": "x", "shape": "sphere", "radius": 0.1, "mass": -1}, r"object 'x'.mass must be > 0"),
        (
            {"name": "x", "shape": "cylinder", "radius": 0.1, "density": 1},
            r"object 'x': a cylinder needs 'radius' and 'length'",
        ),
        (
            {"name": "x", "shape": "sphere", "radius": 0.1, "size": [1, 1, 1], "density": 1},
            r"'size' does not describe a sphere",
        ),
        (
            {"name": "x", "shape": "sphere", "radius": 0.1, "mass": 1, "inertia": [1, 1, 3, 0, 0, 0]},
            r"object 'x'.inertia is not a rigid body's: principal moments \[1.0, 1.0, 3.0\]",
        ),
        (
            {"name": "x", "shape": "sphere", "radius": 0.1, "density": 1, "colour": [1, 0, 0, 1]},
            r"object 'x': unknown key 'colour'",
        ),
        (
            {"name": "x", "shape": "sphere", "radius": 0.1, "density": 1, "color": [2, 0, 0, 1]},
            r"object 'x'.color must be four numbers in \[0, 1\]",
        ),
        (
            {"name": "crank", "shape": "sphere", "radius": 0.1, "density": 1},
            r"object 'crank': the name is already used",
        ),
        (
            {"name": "world", "shape": "sphere", "radius": 0.1, "density": 1},
            r"object 'world': the name is already used",
        ),
        (
            {"name": "x", "shape": "urdf", "urdf": "nowhere.urdf"},
            r"object 'x'.urdf: file .*nowhere.urdf does not exist",
        ),
        (
            {"name": "x", "shape": "urdf", "urdf": str(ROBOTS / "urdf" / "fourbar.urdf")},
            r"an object is one rigid body, but joint",
        ),
    ],
)
def test_bad_objects_are_named(entry, pattern):
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(object_scene([entry]))


def test_urdf_object_takes_mass_and_collision_shape_from_its_file():
    """robots/urdf/box.urdf is one 1 kg box link: its mass, and its collision box for contacts."""
    scene = scene_from_dict(
        object_scene([{"name": "crate", "shape": "urdf", "urdf": str(ROBOTS / "urdf" / "box.urdf")}])
    )
    item = scene.objects[0]
    assert scene.model.inertias[item.joint].mass == pytest.approx(1.0, rel=1e-12)
    assert len(item.geometries) == 1 and isinstance(item.geometries[0][0], coal.Box)
