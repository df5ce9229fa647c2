"""Contact states along event-driven runs (modes, points, world forces per sample) against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from pinstab.errors import PinstabError
from pinstab.scene import load_scene
from pinstab.simulate import simulate
from pinstab.solvers.contact_states import ModeSpan, contact_states, mode_spans, span_at

G, MASS = 9.81, 1.0  # the incline's cube and the balls are 1 kg


def _gravity(scene) -> np.ndarray:
    return MASS * scene.model.gravity.linear


def test_incline_slide_forces_are_the_closed_form():
    """Sliding (mu < tan theta): at every sample the normal forces sum to m g cos theta, the friction forces
    to mu m g cos theta against the slip (down the slope is +x), and with gravity they give the box the
    closed-form acceleration g (sin theta - mu cos theta) along +x (1e-12 relative); the points are the
    cube's bottom corners (Pinocchio's frame placements) on the plane z = 0."""
    theta, mu = 0.5, 0.3
    scene = load_scene("incline", theta=theta, mu=mu)
    run = simulate(scene, dt=0.1, duration=1.0, contacts="event")
    states = contact_states(scene, run)
    assert (states.modes == "sliding").all()
    weight = MASS * G * math.cos(theta)
    np.testing.assert_allclose(states.normal_force.sum(axis=1), weight, rtol=1e-12)
    np.testing.assert_allclose(states.tangential_force.sum(axis=1), mu * weight, rtol=1e-12)
    total = states.forces.sum(axis=1) + _gravity(scene)
    expected = MASS * G * (math.sin(theta) - mu * math.cos(theta)) * np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(total, np.tile(expected, (len(run.t), 1)), atol=1e-12 * G)
    friction = states.forces - states.normal_force[..., None] * states.normals
    np.testing.assert_allclose(friction[..., 0], -mu * states.normal_force, atol=1e-12 * G)
    data = scene.model.createData()
    for sample in (0, -1):
        pin.framesForwardKinematics(scene.model, data, run.q[sample])
        corners = [data.oMf[contact.frame_a].translation for contact in scene.constraints]
        np.testing.assert_allclose(states.points[sample], corners, atol=1e-15)
        np.testing.assert_allclose(states.points[sample][:, 2], 0.0, atol=1e-12)


def test_incline_stick_friction_holds_the_weight_along_the_slope():
    """Sticking (mu > tan theta): the friction forces sum to m g sin theta, the normal forces to
    m g cos theta, and all forces balance gravity (1e-12 relative)."""
    theta = math.radians(20)
    scene = load_scene("incline", theta=theta, mu=0.37)
    run = simulate(scene, dt=0.5, duration=2.0, contacts="event")
    states = contact_states(scene, run)
    assert (states.modes == "sticking").all()
    np.testing.assert_allclose(states.tangential_force.sum(axis=1), MASS * G * math.sin(theta), rtol=1e-12)
    np.testing.assert_allclose(states.normal_force.sum(axis=1), MASS * G * math.cos(theta), rtol=1e-12)
    np.testing.assert_allclose(states.forces.sum(axis=1), -np.tile(_gravity(scene), (len(run.t), 1)), atol=1e-12 * G)


def test_bouncing_ball_is_separated_in_flight_and_holds_its_weight_at_rest():
    """Separated with zero force at every sample before the rest time t0 (1 + e) / (1 - e), sticking with
    force m g up at the ball's lowest point after it; two spans whose bounds are the events' times, and the
    impacts at the events' times."""
    height, e = 1.0, 0.5
    scene = load_scene("bouncing-ball", height=height, restitution=e)
    run = simulate(scene, dt=0.01, duration=2.0, contacts="event")
    states = contact_states(scene, run)
    rest = math.sqrt(2 * height / G) * (1 + e) / (1 - e)
    flight, resting = run.t < rest - 1e-6, run.t > rest + 1e-6
    assert (states.modes[flight] == "separated").all() and (states.modes[resting] == "sticking").all()
    assert (states.forces[flight] == 0.0).all()
    np.testing.assert_allclose(states.forces[resting, 0], np.tile([0.0, 0.0, MASS * G], (resting.sum(), 1)), rtol=1e-9)
    np.testing.assert_allclose(states.points[:, 0, 2], run.q[:, 2] - 0.05, atol=1e-15)
    events = run.info.contact_events
    settle = [x["t"] for x in events if x["to"] == "sticking"]
    (rest_event,) = settle
    assert states.spans == [
        ModeSpan("ground", "separated", 0.0, rest_event),
        ModeSpan("ground", "sticking", rest_event, 2.0),
    ]
    assert [t for t, _ in states.impacts] == [x["t"] for x in events if x["to"] == "closing"]


def test_sphere_spin_slides_against_the_slip_then_rolls_without_friction():
    """sphere-spin (v0 = 2 m/s, omega0 = 5 rad/s, mu = 0.3): sliding before t* = 2 (v0 + r omega0) / (7 mu g)
    with friction mu m g against the slip (-x), rolling after it with zero friction (no other horizontal
    force) and normal force m g."""
    v0, omega0, mu, radius = 2.0, 5.0, 0.3, 0.1
    scene = load_scene("sphere-spin", v0=v0, omega0=omega0, mu=mu, radius=radius)
    run = simulate(scene, dt=0.01, duration=1.0, contacts="event")
    states = contact_states(scene, run)
    t_star = 2 * (v0 + radius * omega0) / (7 * mu * G)
    sliding, rolling = run.t < t_star - 1e-6, run.t > t_star + 1e-6
    assert (states.modes[sliding] == "sliding").all() and (states.modes[rolling] == "sticking").all()
    np.testing.assert_allclose(states.forces[sliding, 0], np.tile([-mu * MASS * G, 0, MASS * G], (sliding.sum(), 1)))
    np.testing.assert_allclose(states.forces[rolling, 0, :2], 0.0, atol=1e-12)
    np.testing.assert_allclose(states.normal_force[:, 0], MASS * G, rtol=1e-12)
    (switch,) = [span.start for span in states.spans if span.mode == "sticking"]
    assert abs(switch - t_star) <= 1e-8


def test_a_slide_from_rest_takes_the_direction_of_its_event_force():
    """From rest the slip speed is 0 at the first sample: the span carries the direction opposite the start
    event's friction force, (1, 0) without friction; an event a sliver of a step late belongs to the sample."""
    events = [
        {"t": 0.0, "contact": "c", "to": "sliding", "force": [2.0, 0.0, -0.6]},
        {"t": 0.5, "contact": "c", "to": "closing", "force": [0.0, 0.0, 0.0]},
        {"t": 0.5, "contact": "c", "to": "sticking", "force": [1.0, 0.0, 0.0]},
    ]
    spans = mode_spans(events, ["c"], 1.0)
    assert spans[0] == ModeSpan("c", "sliding", 0.0, 0.5, (0.0, 1.0))
    assert span_at(spans, 0.5 - 1e-12).mode == "sliding"
    assert span_at(spans, 0.5 - 1e-12, slack=1e-11).mode == "sticking"
    assert mode_spans([{**events[0], "force": [2.0, 0.0, 0.0]}], ["c"], 1.0)[0].direction == (1.0, 0.0)


def test_runs_and_scenes_that_do_not_match_are_refused():
    scene = load_scene("bouncing-ball")
    run = simulate(scene, dt=0.1, duration=0.2, contacts="event")
    with pytest.raises(PinstabError, match="no contact events"):
        contact_states(scene, simulate("fourbar", dt=0.01, duration=0.02))
    with pytest.raises(PinstabError, match="scene fourbar has no plane contacts"):
        contact_states(load_scene("fourbar"), run)
    with pytest.raises(PinstabError, match="'ground': no such contact; contacts: corner0, corner1"):
        contact_states(load_scene("incline"), run)
    run.q = run.q[:, :6]
    with pytest.raises(PinstabError, match="7 configuration coordinates, the run 6"):
        contact_states(scene, run)
    with pytest.raises(PinstabError, match="'elsewhere': no such contact; contacts: ground"):
        mode_spans([{"t": 0.0, "contact": "elsewhere", "to": "sticking", "force": [0, 0, 0]}], ["ground"], 1.0)
    with pytest.raises(PinstabError, match="contact 'ground' has no events"):
        mode_spans([{"t": 0.0, "contact": "ground", "to": "closing", "force": [0, 0, 0]}], ["ground"], 1.0)
