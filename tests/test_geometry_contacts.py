"""Contacts found from collision geometry with coal (issue 36, kind ``geometry``) against the declared contacts
of the same scenes and their closed forms: incline, sphere-spin, bouncing-ball, a box at rest on the ground."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from pinstab.errors import SceneError
from pinstab.scene import load_scene, scene_from_dict
from pinstab.simulate import simulate

G = 9.81
EVENT_KEYS = ("from", "to", "cause")


def geometry_scene(generator: str, parameters: dict | None = None, **entry):
    """The bundled generator's scene with its declared contacts replaced by contacts found from geometry."""
    data = {"generator": {"name": generator, **(parameters or {})}, "contacts": [{"kind": "geometry", **entry}]}
    return scene_from_dict(data, name=generator)


def assert_same_events(found, declared, names: dict[str, str]) -> None:
    """The same events, in order, at the same times (to 1e-9 s), the found contacts renamed to the declared."""
    assert len(found) == len(declared)
    for ours, theirs in zip(found, declared, strict=True):
        assert names[ours["contact"]] == theirs["contact"]
        cause = ours["cause"]
        for name, declared_name in names.items():  # a cause names the contact that reached its bound
            cause = cause.replace(name, declared_name)
        assert [ours["from"], ours["to"], cause] == [theirs[k] for k in EVENT_KEYS]
        assert abs(ours["t"] - theirs["t"]) <= 1e-9


def test_box_corners_are_found_with_stable_names():
    scene = geometry_scene("incline", mu=0.3)
    declared = load_scene("incline", mu=0.3)
    assert [c.name for c in scene.constraints] == [f"box_0/ground[{k}]" for k in (1, 3, 5, 7)]
    for found, corner in zip(scene.constraints, declared.constraints, strict=True):
        # the bottom corners, in the declared order, on the plane z = 0 with the scene's friction
        offset = scene.model.frames[found.frame_a].placement.translation
        np.testing.assert_array_equal(offset, declared.model.frames[corner.frame_a].placement.translation)
        np.testing.assert_array_equal(found.plane_point, corner.plane_point)
        assert found.friction == corner.friction and found.radius == 0.0


@pytest.mark.parametrize(("theta", "mu"), [(math.radians(20), 0.37), (0.0, 0.3)])
def test_incline_and_a_resting_box_stick_without_creep(theta, mu):
    """Below the friction angle (and on a level ground: a box at rest on its four corners found from its shape)
    the box holds still to 1e-10 m, with the declared run's events."""
    parameters = {"theta": theta, "mu": mu}
    run = simulate(geometry_scene("incline", parameters, mu=mu), dt=0.1, duration=10.0, contacts="event")
    assert np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-10
    declared = simulate(load_scene("incline", **parameters), dt=0.1, duration=10.0, contacts="event")
    names = {f"box_0/ground[{k}]": f"corner{j}" for j, k in enumerate((1, 3, 5, 7))}
    assert_same_events(run.info.contact_events, declared.info.contact_events, names)


def test_incline_slides_as_the_closed_form():
    theta, mu = 0.5, 0.3
    run = simulate(geometry_scene("incline", {"theta": theta}, mu=mu), dt=0.01, duration=2.0, contacts="event")
    exact = G * (math.sin(theta) - mu * math.cos(theta)) * 2.0**2 / 2
    assert abs(run.q[-1, 0] - exact) <= 1e-8 * exact
    assert {e["to"] for e in run.info.contact_events} == {"sliding"}


def test_sphere_spin_rolls_at_the_closed_form_time_and_speed():
    v0, omega0, mu, radius = 2.0, 5.0, 0.3, 0.1
    scene = geometry_scene("sphere-spin", mu=mu)
    assert [c.radius for c in scene.constraints] == [radius]  # the ball's coal sphere
    run = simulate(scene, dt=0.01, duration=1.0, contacts="event")
    switches = [e for e in run.info.contact_events if e["to"] == "sticking"]
    assert len(switches) == 1
    assert abs(switches[0]["t"] - 2 * (v0 + radius * omega0) / (7 * mu * G)) <= 1e-8
    data = scene.model.createData()
    pin.forwardKinematics(scene.model, data, run.q[-1], run.v[-1])
    speed = pin.getVelocity(scene.model, data, 1, pin.LOCAL_WORLD_ALIGNED).linear[0]
    rolling = (5 * v0 - 2 * radius * omega0) / 7
    assert abs(speed - rolling) <= 1e-8 * rolling
    declared = simulate("sphere-spin", dt=0.01, duration=1.0, contacts="event")
    assert_same_events(run.info.contact_events, declared.info.contact_events, {"ball_0/ground[0]": "ground"})


def test_bouncing_ball_apexes_and_rest():
    height, e = 1.0, 0.5
    run = simulate(geometry_scene("bouncing-ball", restitution=e), dt=0.01, duration=2.0, contacts="event")
    impacts = [x["t"] for x in run.info.contact_events if x["to"] == "closing"]
    t0 = math.sqrt(2 * height / G)
    exact = [t0 + 2 * t0 * sum(e**j for j in range(1, k + 1)) for k in range(6)]
    np.testing.assert_allclose(impacts[:6], exact, rtol=1e-8)
    flights = np.diff(impacts[:6])  # apex gaps e^(2k) h from the flight times between impacts: (g/8) T_k^2
    np.testing.assert_allclose(G * flights**2 / 8, height * e ** (2 * np.arange(1, 6)), rtol=1e-8)
    assert abs(run.q[-1, 2] - 0.05) <= 1e-9
    declared = simulate("bouncing-ball", dt=0.01, duration=2.0, contacts="event")
    assert_same_events(run.info.contact_events, declared.info.contact_events, {"ball_0/ground[0]": "ground"})


def test_runs_are_deterministic_to_the_last_bit():
    runs = [simulate(geometry_scene("sphere-spin", mu=0.3), dt=0.01, duration=0.5, contacts="event") for _ in range(2)]
    np.testing.assert_array_equal(runs[0].q, runs[1].q)
    np.testing.assert_array_equal(runs[0].v, runs[1].v)
    assert runs[0].info.contact_events == runs[1].info.contact_events


def test_a_bad_pair_name_is_named_with_the_shapes():
    with pytest.raises(SceneError, match=r"'floor'.*shapes: box_0, ground"):
        geometry_scene("incline", pairs=[["box_0", "floor"]])
    with pytest.raises(SceneError, match=r"pairs must be a list of \[shape, shape\]"):
        geometry_scene("incline", pairs=["box_0/ground"])
    with pytest.raises(SceneError, match="unknown key 'name'"):
        geometry_scene("incline", name="corners")


def test_no_ground_leaves_no_pair():
    with pytest.raises(SceneError, match="no pair of collision shapes may touch; shapes: box_0"):
        geometry_scene("incline", ground=False)


def test_a_tilted_box_drop_finds_its_corners_as_they_come():
    """A frictionless box dropped on a corner: the scene starts with that corner alone, the run finds the others
    as they come near (coal at every step's end) and has the events of all eight corners declared (to the rattle of
    two corners nanoseconds apart at t = 0.2716 s, whose count rounding decides), ending at rest on a face (the
    declared run's state to 1e-9)."""
    quaternion = pin.Quaternion(pin.rpy.rpyToMatrix(0.3, 0.2, 0.0)).coeffs().tolist()
    data = {"generator": {"name": "incline", "theta": 0.0}, "initial": {"q": {"root_joint": [0, 0, 0.3, *quaternion]}}}
    found = scene_from_dict({**data, "contacts": [{"kind": "geometry", "mu": 0.0}]}, name="drop")
    assert [c.name for c in found.constraints] == ["box_0/ground[3]"]
    corners = [[sx * 0.05, sy * 0.05, sz * 0.05] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
    entries = [
        {"name": f"c{k}", "kind": "plane-contact", "frame_a": "box", "offset_a": p, "mu": 0.0}
        for k, p in enumerate(corners)
    ]
    declared = scene_from_dict({**data, "contacts": entries}, name="drop")
    runs = [simulate(scene, dt=0.01, duration=1.5, contacts="event") for scene in (found, declared)]
    names = {f"box_0/ground[{k}]": f"c{k}" for k in range(8)}
    early = [[e for e in run.info.contact_events if e["cause"] != "start" and e["t"] < 0.2715] for run in runs]
    assert len(early[0]) >= 10
    assert_same_events(*early, names)
    assert {e["contact"] for e in runs[0].info.contact_events} == {f"box_0/ground[{k}]" for k in (1, 3, 5, 7)}
    assert np.max(np.abs(runs[0].q[-1] - runs[1].q[-1])) <= 1e-9
    assert abs(runs[0].q[-1, 2] - 0.05) <= 1e-9 and np.max(np.abs(runs[0].v[-1])) <= 1e-9


def test_a_finder_asked_again_keeps_its_contacts_and_makes_no_features(monkeypatch):
    """The contacts of a box at its start and slid 1 mm along the ground are the four corners the scene found, the
    same objects, without their Feature tuples made again (the compiled finder found the same features); tilted 0.2
    rad about a bottom edge, two corners stay (the same objects) and the features are made for it, once."""
    scene = geometry_scene("incline", mu=0.3)
    finder = scene.contact_finders[0]
    made = []
    features_of = finder.shapes.features_of
    monkeypatch.setattr(finder.shapes, "features_of", lambda found: made.append(found) or features_of(found))
    first = finder.contacts(scene.q0)
    slid = scene.q0.copy()
    slid[0] += 1e-3
    again = finder.contacts(slid)
    assert [c.name for c in first] == [f"box_0/ground[{k}]" for k in (1, 3, 5, 7)]
    assert all(a is b for a, b in zip(again, first, strict=True)) and first == scene.constraints and not made
    edge = np.array([-0.05, 0.0, 0.0])  # the box's -x bottom edge [m] from its centre; the box on it, tilted up
    turn = pin.SE3(pin.rpy.rpyToMatrix(0.0, -0.2, 0.0), np.zeros(3))
    placed = pin.XYZQUATToSE3(scene.q0[:7]) * pin.SE3(np.eye(3), edge + [0, 0, -0.05]) * turn
    placed = placed * pin.SE3(np.eye(3), -(edge + [0, 0, -0.05]))
    tilted = scene.q0.copy()
    tilted[:7] = pin.SE3ToXYZQUAT(placed)
    left = finder.contacts(tilted)
    assert [c.name for c in left] == [f"box_0/ground[{k}]" for k in (5, 7)] and len(made) == 1
    assert left[0] is first[2] and left[1] is first[3]
    assert finder.contacts(tilted) == left and len(made) == 1
