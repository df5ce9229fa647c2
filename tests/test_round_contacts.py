"""Round pairs found from geometry (issue 36): a sphere against a fixed sphere or capsule, its contact on the line of
centres re-computed at every state, against the closed forms of a ball leaving the top of a fixed ball (frictionless:
cos theta = 2/3 cos theta0; rolling: 2 sin theta = mu (17 cos theta - 10 cos theta0) where it slips) and of a ball
resting in a V of two fixed balls (each normal force m g / (2 cos alpha))."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from pinstab.contact.modes import Mode
from pinstab.contact.round_pairs import core_nearest
from pinstab.errors import SceneError
from pinstab.model import ConstrainedModel
from pinstab.scene import scene_from_dict
from pinstab.simulate import simulate
from pinstab.solvers.contact_modes import ModeDynamics, plane_geometries

G = 9.81
R, r = 0.5, 0.1  # [m] the fixed ball's and the moving ball's radii
THETA0 = 0.1  # [rad] the moving ball's start from the top, at rest
ROBOTS = Path(__file__).resolve().parents[1] / "robots"


def fixed_urdf(shapes: list[str]) -> str:
    """A robot without joints whose one link carries the collision ``shapes`` (URDF ``<collision>`` bodies)."""
    bodies = "".join(f"<collision>{shape}</collision>" for shape in shapes)
    return f'<?xml version="1.0"?><robot name="fixed"><link name="base">{bodies}</link></robot>'


def sphere(x: float, radius: float) -> str:
    return f'<origin xyz="{x} 0 0"/><geometry><sphere radius="{radius}"/></geometry>'


def ball_scene(fixed: list[str], position: list[float], **contact) -> object:
    """A 1 kg ball of radius r at ``position`` [m] among the ``fixed`` shapes, no ground, contacts from geometry."""
    body = {"shape": "sphere", "radius": r}
    data = {
        "robot": {"urdf_text": fixed_urdf(fixed)},
        "gravity": [0.0, 0.0, -G],
        "objects": [{"name": "ball", **body, "mass": 1.0, "position": position}],
        "contacts": [{"kind": "geometry", "ground": False, **contact}],
    }
    return scene_from_dict(data, name="round-pair")


def on_top() -> list[float]:
    """The moving body's centre THETA0 from the top of the fixed ball, touching it [m]."""
    return [(R + r) * math.sin(THETA0), 0.0, (R + r) * math.cos(THETA0)]


def test_a_ball_slides_off_a_fixed_ball_where_the_closed_form_says():
    """Frictionless, from rest THETA0 from the top: it leaves at cos theta = (2/3) cos THETA0 (1e-9) with the speed
    of the height lost, v^2 = 2 g (R + r)(cos THETA0 - cos theta) (1e-9), its centre on the fixed surface to 1e-9 m,
    without turning."""
    scene = ball_scene([sphere(0.0, R)], on_top())
    assert [c.name for c in scene.constraints] == ["ball/collision0/base_0[0]"]
    run = simulate(scene, contacts="event", duration=1.0, dt=0.01, stop_on={"separation"})
    assert run.info.stopped is not None
    x = run.q[-1, :3]
    distance = float(np.linalg.norm(x))
    cos = x[2] / distance
    assert abs(distance - (R + r)) <= 1e-9
    assert abs(cos - 2.0 / 3.0 * math.cos(THETA0)) <= 1e-9
    speed2 = float(run.v[-1, :3] @ run.v[-1, :3])
    assert abs(speed2 - 2 * G * (R + r) * (math.cos(THETA0) - cos)) <= 1e-9
    assert abs(run.q[-1, 1]) <= 1e-12 and np.max(np.abs(run.v[:, 3:])) <= 1e-9  # it does not turn


@pytest.mark.parametrize("mu", [0.2, 0.5])
def test_a_ball_rolls_off_a_fixed_ball_and_slips_where_the_closed_form_says(mu):
    """With friction it rolls from THETA0 (sticking, friction (2/7) m g sin THETA0 at the start), its speed that of
    rolling, v^2 = (10/7) g (R + r)(cos THETA0 - cos theta), and slips where the friction (2/7) m g sin theta reaches
    mu N, N = m g (17 cos theta - 10 cos THETA0) / 7 (both 1e-9), then leaves the ball (it always slips first: at
    N = 0 rolling needs friction)."""
    scene = ball_scene([sphere(0.0, R)], on_top(), mu=mu)
    events = simulate(scene, contacts="event", duration=1.0, dt=0.01).info.contact_events
    assert [(e["from"], e["to"]) for e in events] == [
        ("separated", "sticking"),
        ("sticking", "sliding"),
        ("sliding", "separated"),
    ]
    assert abs(events[0]["force"][1] - 2 / 7 * G * math.sin(THETA0)) <= 1e-12
    run = simulate(scene, contacts="event", duration=1.0, dt=0.01, stop_on={"slip"})
    x = run.q[-1, :3]
    cos, sin = x[2] / np.linalg.norm(x), x[0] / np.linalg.norm(x)
    assert abs(2 * sin - mu * (17 * cos - 10 * math.cos(THETA0))) <= 1e-9
    speed2 = float(run.v[-1, :3] @ run.v[-1, :3])
    assert abs(speed2 - 10 / 7 * G * (R + r) * (math.cos(THETA0) - cos)) <= 1e-9


def test_a_ball_in_a_v_of_two_fixed_balls_carries_its_weight_by_the_closed_form():
    """Frictionless, resting on two fixed balls 2 a apart: each pushes m g / (2 cos alpha) along its line of centres
    (cos alpha = h / (R + r)) within 1e-9 N, and the ball stays put for 2 s (1e-12 m)."""
    half = 0.3
    height = math.sqrt((R + r) ** 2 - half**2)
    scene = ball_scene([sphere(half, R), sphere(-half, R)], [0.0, 0.0, height])
    dynamics = ModeDynamics(
        ConstrainedModel(dataclasses.replace(scene, constraints=[])), plane_geometries(scene.constraints)
    )
    q, v = scene.q0, np.zeros(scene.model.nv)
    forces = dynamics.solve(q, v, 0.0, [Mode.SLIDING, Mode.SLIDING]).forces
    np.testing.assert_allclose(forces[:, 0], G / (2 * height / (R + r)), rtol=0.0, atol=1e-9)
    assert np.all(forces[:, 1:] == 0.0)
    run = simulate(scene, contacts="event", duration=2.0, dt=0.1)
    assert np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-12


def test_the_nearest_point_of_a_capsule_core():
    """A point beside the segment: its foot, the projector across the axis; beyond an end: the end, the identity."""
    ends = np.array([[0.0, 0.0, -0.2], [0.0, 0.0, 0.2]])
    nearest, projector = core_nearest(np.array([0.3, 0.4, 0.1]), ends)
    np.testing.assert_allclose(nearest, [0.0, 0.0, 0.1], rtol=0.0, atol=1e-16)
    np.testing.assert_allclose(projector, np.diag([1.0, 1.0, 0.0]), atol=1e-16)
    nearest, projector = core_nearest(np.array([0.3, 0.4, 0.5]), ends)
    np.testing.assert_array_equal(nearest, ends[1])
    np.testing.assert_array_equal(projector, np.eye(3))


def test_a_ball_in_a_v_of_two_ground_planes_carries_its_weight_by_the_closed_form():
    """``ground`` as a list of planes (half-spaces ``ground``, ``ground_1``): a frictionless ball resting in the V
    of two planes tilted by alpha pushes on each with m g / (2 cos alpha) (1e-9 N)."""
    alpha = math.radians(30.0)
    planes = [{"normal": [math.sin(s * alpha), 0.0, math.cos(alpha)], "point": [0.0, 0.0, 0.0]} for s in (1, -1)]
    data = {
        "robot": {"urdf_text": fixed_urdf([])},
        "gravity": [0.0, 0.0, -G],
        "objects": [
            {"name": "ball", "shape": "sphere", "radius": r, "mass": 1.0, "position": [0, 0, r / math.cos(alpha)]}
        ],
        "contacts": [{"kind": "geometry", "ground": planes}],
    }
    scene = scene_from_dict(data, name="v-planes")
    assert [c.name for c in scene.constraints] == ["ball/collision0/ground[0]", "ball/collision0/ground_1[0]"]
    dynamics = ModeDynamics(
        ConstrainedModel(dataclasses.replace(scene, constraints=[])), plane_geometries(scene.constraints)
    )
    forces = dynamics.solve(scene.q0, np.zeros(scene.model.nv), 0.0, [Mode.SLIDING, Mode.SLIDING]).forces
    np.testing.assert_allclose(forces[:, 0], G / (2 * math.cos(alpha)), rtol=0.0, atol=1e-9)


def test_the_new_keys_are_checked():
    """grasp-contact ``surface``, grasp-hold ``release`` and the tilt's ``stop``: bad values refused, naming the
    valid ones."""
    with pytest.raises(SceneError, match=r"surface: unknown surface 'curved'; surfaces: plane, round"):
        scene_from_dict(_allegro(surface="curved"), name="bad")
    with pytest.raises(SceneError, match=r"release: unknown release 'drop'; releases: press, relax"):
        scene_from_dict(_allegro(release="drop"), name="bad")
    with pytest.raises(SceneError, match=r"tilt.stop must be an angle the turn reaches"):
        scene_from_dict(_allegro(stop="1 deg"), name="bad")


def _allegro(surface: str = "round", release: str = "relax", stop: str = "1.9 deg") -> dict:
    """allegro-drop's table with one value changed."""
    data = tomllib.loads((ROBOTS / "allegro-drop.toml").read_text())
    for contact in data["contacts"]:
        if contact["kind"] == "grasp-contact":
            contact["surface"] = surface
    data["forces"][0]["release"] = release
    data["tilt"]["stop"] = stop
    return data
