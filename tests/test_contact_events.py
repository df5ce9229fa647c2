"""Event-driven contacts (issue 21) against closed forms: incline, sphere-spin, bouncing-ball."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from pinstab.errors import SceneError
from pinstab.scene import load_scene
from pinstab.simulate import simulate

G = 9.81


def test_incline_slides_as_the_closed_form():
    theta, mu = 0.5, 0.3
    run = simulate(load_scene("incline", theta=theta, mu=mu), dt=0.01, duration=2.0, contacts="event")
    exact = G * (math.sin(theta) - mu * math.cos(theta)) * 2.0**2 / 2
    assert abs(run.q[-1, 0] - exact) <= 1e-8 * exact
    assert {e["to"] for e in run.info.contact_events} == {"sliding"}


def test_incline_sticks_below_the_friction_angle_without_creep():
    theta = math.radians(20)
    mu = 0.37  # just above tan(20 deg) = 0.364: the smallest-norm forces leave the uphill corners' cones
    run = simulate(load_scene("incline", theta=theta, mu=mu), dt=0.1, duration=10.0, contacts="event")
    assert np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-10
    assert {e["to"] for e in run.info.contact_events} == {"sticking"}


def test_sphere_spin_rolls_at_the_closed_form_time_and_speed():
    v0, omega0, mu, radius = 2.0, 5.0, 0.3, 0.1
    scene = load_scene("sphere-spin")
    run = simulate(scene, dt=0.01, duration=1.0, contacts="event")
    switches = [e for e in run.info.contact_events if e["to"] == "sticking"]
    assert len(switches) == 1
    assert abs(switches[0]["t"] - 2 * (v0 + radius * omega0) / (7 * mu * G)) <= 1e-8
    model = scene.model
    data = model.createData()
    pin.forwardKinematics(model, data, run.q[-1], run.v[-1])
    speed = pin.getVelocity(model, data, 1, pin.LOCAL_WORLD_ALIGNED).linear[0]
    rolling = (5 * v0 - 2 * radius * omega0) / 7
    assert abs(speed - rolling) <= 1e-8 * rolling


def test_bouncing_ball_impacts_and_rest_time():
    height, e = 1.0, 0.5
    run = simulate("bouncing-ball", dt=0.01, duration=2.0, contacts="event")
    impacts = [x["t"] for x in run.info.contact_events if x["to"] == "closing"]
    t0 = math.sqrt(2 * height / G)
    exact = [t0 + 2 * t0 * sum(e**j for j in range(1, k + 1)) for k in range(6)]
    np.testing.assert_allclose(impacts[:6], exact, rtol=1e-8)
    # apex gaps e^(2k) h follow from the flight times between impacts: (g/8) T_k^2
    flights = np.diff(impacts[:6])
    np.testing.assert_allclose(G * flights**2 / 8, height * e ** (2 * np.arange(1, 6)), rtol=1e-8)
    rest = run.info.contact_events[-1]
    assert rest["to"] == "sticking"
    assert abs(rest["t"] - t0 * (1 + e) / (1 - e)) <= 1e-6 * t0 * (1 + e) / (1 - e)
    assert abs(run.q[-1, 2] - 0.05) <= 1e-9  # at rest on the plane


@pytest.mark.parametrize(("key", "value"), [("restitution", 1.5), ("radius", -0.1)])
def test_bad_contact_parameters_are_named(key, value):
    data = {
        "robot": {"urdf": "urdf/box.urdf", "free_flyer": True},
        "contacts": [{"name": "c", "kind": "plane-contact", "frame_a": "box", key: value}],
    }
    from pinstab.robots import bundled_dir
    from pinstab.scene import scene_from_dict

    with pytest.raises(SceneError, match=key):
        scene_from_dict(data, base_dir=bundled_dir())


def test_bad_generator_parameters_are_named():
    with pytest.raises(SceneError, match="mu"):
        load_scene("incline", mu=-0.1)
