"""Contacts found from geometry, second slice (issue 36): a stack of boxes (bodies against bodies, redundant corners),
cylinders, and the time-stepping contacts finding them at every step, against closed forms, the conservation of
the weight carried down the stack and the same contacts declared (``plane-contact``, ``frame_b`` for a box's face)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from test_geometry_contacts import assert_same_events

from pinstab.bench.box_stack import HALF, TOP_CORNERS, declared_stack
from pinstab.errors import SceneError
from pinstab.generators import BOX_SIDE, GROUND_URDF
from pinstab.scene import load_scene, scene_from_dict
from pinstab.simulate import default_contacts, simulate

G = 9.81


def creep(q: np.ndarray, bodies: int) -> float:
    """The largest displacement [m] and turn [rad] of ``bodies`` free bodies (7 coordinates each) from q[0]."""
    worst = 0.0
    for b in range(bodies):
        position, orientation = q[:, 7 * b : 7 * b + 3], q[:, 7 * b + 3 : 7 * b + 7]
        start = pin.Quaternion(orientation[0]).matrix()
        turns = [np.linalg.norm(pin.log3(start.T @ pin.Quaternion(o).matrix())) for o in orientation]
        worst = max(worst, float(np.max(np.abs(position - position[0]))), max(turns))
    return worst


def test_box_stack_rests_without_creep_carrying_the_weight_above():
    """Three boxes at rest for 10 s: 12 redundant corners (4 per face pair) sticking from the start, no other
    event, every box within 1e-10 m and rad of its start; the normal forces under box k sum to (3 - k) m g."""
    scene = load_scene("box-stack")
    assert default_contacts(scene) == "event"  # 20 contacts found (8 of boxes 1, 2 on the far ground): events
    run = simulate(scene, dt=0.1, duration=10.0, contacts="event")
    assert creep(run.q, 3) <= 1e-10
    events = run.info.contact_events
    assert {e["cause"] for e in events} == {"start"} and len(events) == len(scene.constraints)
    under = {"box0/collision0/ground": 3, "box0/collision0/box1/collision0": 2, "box1/collision0/box2/collision0": 1}
    for pair, boxes in under.items():
        touching = [e for e in events if e["contact"].startswith(pair + "[")]
        assert [e["to"] for e in touching] == ["sticking"] * 4
        total = sum(e["force"][0] for e in touching)
        assert abs(total - boxes * G) <= 1e-9 * boxes * G
    far = [e for e in events if e["to"] == "separated"]
    assert {e["contact"].split("[")[0] for e in far} == {"box1/collision0/ground", "box2/collision0/ground"}


def test_box_stack_matches_the_declared_corners():
    """The stack with its 20 corners declared (those on the boxes' faces carried by the box above): the same
    start modes and the same state after 2 s (to 1e-10, the creep allowed: the rounding of two orders of rows)."""
    names = ["box0", "box1", "box2"]
    entries, renames = declared_stack(names, 0.5)
    found = load_scene("box-stack")
    declared = scene_from_dict({"generator": {"name": "box-stack"}, "contacts": entries}, name="declared")
    runs = [simulate(scene, dt=0.1, duration=2.0, contacts="event") for scene in (found, declared)]
    modes = [{renames.get(e["contact"], e["contact"]): e["to"] for e in run.info.contact_events} for run in runs]
    assert modes[0] == modes[1]
    assert np.max(np.abs(runs[0].q[-1] - runs[1].q[-1])) <= 1e-10


DROP = 0.1  # [m] beyond the broad phase at the start: the dropped box's contacts are found as it comes near


def test_a_box_dropped_on_the_stack_lands_at_the_closed_form_time_and_rests():
    """A box released 0.1 m above the stack: its contacts with the top box are found on the way (none at the
    start), its four corners close at sqrt(2 h / g) (1e-9 s) in one impact that stops it (e = 0), every contact
    then sticks and nothing happens after: at rest on the top at 0.35 m (1e-9) with the same events as the
    corners declared."""
    scene = load_scene("box-stack", drop=DROP)
    assert not any(c.name.startswith("box2/collision0/dropped") for c in scene.constraints)
    run = simulate(scene, dt=0.01, duration=1.0, contacts="event")
    later = [e for e in run.info.contact_events if e["cause"] != "start"]
    landing = math.sqrt(2 * DROP / G)
    assert {round(e["t"], 12) for e in later} == {round(later[0]["t"], 12)}
    assert abs(later[0]["t"] - landing) <= 1e-9
    closed = [e["contact"] for e in later if e["from"] == "separated"]
    assert closed == [f"box2/collision0/dropped/collision0[{k}]" for k in TOP_CORNERS]
    assert [e["to"] for e in later if e["from"] == "closing"] == ["sticking"] * 16
    assert abs(run.q[-1, 23] - (3 * BOX_SIDE + HALF)) <= 1e-9 and np.max(np.abs(run.v[-1])) <= 1e-9
    entries, renames = declared_stack(["box0", "box1", "box2", "dropped"], 0.5)
    declared_scene = scene_from_dict({"generator": {"name": "box-stack", "drop": DROP}, "contacts": entries}, name="d")
    declared = simulate(declared_scene, dt=0.01, duration=1.0, contacts="event")
    kept = [e for e in declared.info.contact_events if e["cause"] != "start"]
    order = {name: k for k, name in enumerate(renames.values())}  # the impact's events in the declared order
    assert_same_events(
        sorted(later, key=lambda e: (e["t"], e["from"] == "closing", order[renames[e["contact"]]])), kept, renames
    )
    assert np.max(np.abs(run.q[-1] - declared.q[-1])) <= 1e-9


def test_stepping_finds_the_dropped_box_and_rests_where_the_event_run_does():
    """Time-stepping contacts (dt = 1 ms) ask coal at every step: the dropped box lands on the stack, rests at
    0.35 m (1e-9) and every body ends where the event-driven run ends (1e-6); the stack holds still under it
    (its contacts solved together with those the impulses close: none opens)."""
    scene = load_scene("box-stack", drop=DROP)
    stepped = simulate(scene, dt=1e-3, duration=0.6, contacts="stepping")
    events = simulate(load_scene("box-stack", drop=DROP), dt=0.01, duration=0.6, contacts="event")
    assert abs(stepped.q[-1, 23] - (3 * BOX_SIDE + HALF)) <= 1e-9 and np.max(np.abs(stepped.v[-1])) <= 1e-9
    assert np.max(np.abs(stepped.q[-1] - events.q[-1])) <= 1e-6
    assert creep(stepped.q, 3) <= 1e-9
    landed = [e for e in stepped.info.contact_events if e["cause"] != "start"]
    assert {e["contact"] for e in landed} == {f"box2/collision0/dropped/collision0[{k}]" for k in TOP_CORNERS}
    assert {e["to"] for e in landed} == {"sticking"}
    assert abs(landed[0]["t"] - math.sqrt(2 * DROP / G)) <= 1e-3  # located to within a step


def can_scene(rpy: list[float], z: float, gravity: list[float], mu: float = 0.5, under: dict | None = None):
    """A 1 kg cylinder (radius 0.05 m, length 0.2 m) placed at height z [m] with ``rpy`` [rad], contacts found
    (``under``: an object added before it)."""
    objects = [{"name": "can", "shape": "cylinder", "radius": 0.05, "length": 0.2, "mass": 1.0}]
    objects[0] |= {"position": [0.0, 0.0, z], "rpy": rpy}
    if under is not None:
        objects.insert(0, under)
    data = {"robot": {"urdf_text": GROUND_URDF}, "gravity": gravity, "objects": objects}
    return scene_from_dict({**data, "contacts": [{"kind": "geometry", "mu": mu}]}, name="can")


@pytest.mark.parametrize("theta", [0.3, 0.6])
def test_a_cylinder_rolls_down_an_incline_at_two_thirds_g_sin_theta(theta):
    """On its side (its two end caps' lowest points, mu = 0.5 above tan(theta) / 3) a solid cylinder rolls
    without slip: x = g sin(theta) t^2 / 3, its spin x' / r, to 1e-9 relative at the end."""
    gravity = [G * math.sin(theta), 0.0, -G * math.cos(theta)]
    scene = can_scene([math.pi / 2, 0.0, 0.0], 0.05, gravity)
    assert [(c.name, c.radius) for c in scene.constraints] == [(f"can/collision0/ground[{k}]", 0.05) for k in (0, 1)]
    run = simulate(scene, dt=0.01, duration=1.0, contacts="event")
    exact = G * math.sin(theta) * run.t**2 / 3
    assert abs(run.q[-1, 0] - exact[-1]) <= 1e-9 * exact[-1]
    assert np.max(np.abs(run.q[:, 0] - exact)) <= 1e-7 * exact[-1]  # samples between steps: the dense output's
    assert np.max(np.abs(run.q[-1, 1:3] - run.q[0, 1:3])) <= 1e-10  # across, height: on the plane
    assert np.max(np.abs(run.q[:, 1:3] - run.q[0, 1:3])) <= 1e-8
    spin = np.linalg.norm(run.v[-1, 3:])  # the body twist's angular part: about the axis
    assert abs(spin * 0.05 - 2 * G * math.sin(theta) / 3) <= 1e-9 * spin * 0.05
    assert {e["to"] for e in run.info.contact_events} == {"sticking"}


def test_a_cylinder_slides_when_the_friction_cannot_roll_it():
    """Below mu = tan(theta) / 3 the cap points slide: the centre accelerates at g (sin - mu cos) (1e-9)."""
    theta, mu = 0.6, 0.1
    scene = can_scene([math.pi / 2, 0.0, 0.0], 0.05, [G * math.sin(theta), 0.0, -G * math.cos(theta)], mu)
    run = simulate(scene, dt=0.01, duration=1.0, contacts="event")
    exact = G * (math.sin(theta) - mu * math.cos(theta)) / 2
    assert abs(run.q[-1, 0] - exact) <= 1e-9 * exact


TABLE = {"name": "table", "shape": "box", "size": [0.3, 0.3, 0.1], "mass": 2.0, "position": [0.0, 0.0, 0.05]}


@pytest.mark.parametrize(
    ("rpy", "height", "points"),
    [([0.0, 0.0, 0.0], 0.1, list(range(10, 18))), ([math.pi / 2, 0.0, 0.0], 0.05, [0, 1])],
    ids=["standing", "lying"],
)
def test_a_cylinder_rests_on_the_ground(rpy, height, points):
    """Standing on its -z cap (the 8 rim points there) or lying on its side (its caps' lowest points): at rest
    for 10 s within 1e-10 m and rad, its contacts carrying m g (1e-9 relative)."""
    scene = can_scene(rpy, height, [0.0, 0.0, -G])
    assert [c.name for c in scene.constraints] == [f"can/collision0/ground[{k}]" for k in points]
    run = simulate(scene, dt=0.1, duration=10.0, contacts="event")
    assert creep(run.q, 1) <= 1e-10
    assert {e["cause"] for e in run.info.contact_events} == {"start"}
    assert abs(sum(e["force"][0] for e in run.info.contact_events) - G) <= 1e-9 * G


def test_a_cylinder_rests_on_a_box_face():
    """Standing on a 2 kg box's top face (its rim points against the face, carried by the box): both at rest for
    10 s within 1e-10 m and rad; the rim carries m g, the box's corners 3 m g. Lying on its side there, its caps'
    lowest points carry m g at the start (its rolling is neutral: the box's own rounding tilt of 3e-12 rad rolls it
    5e-9 rad in 10 s)."""
    standing = can_scene([0.0, 0.0, 0.0], 0.2, [0.0, 0.0, -G], under=TABLE)
    run = simulate(standing, dt=0.1, duration=10.0, contacts="event")
    assert creep(run.q, 2) <= 1e-10
    forces = {name: 0.0 for name in ("can/collision0/table/collision0", "table/collision0/ground")}
    for event in run.info.contact_events:
        forces[event["contact"].split("[")[0]] = forces.get(event["contact"].split("[")[0], 0.0) + event["force"][0]
    assert abs(forces["can/collision0/table/collision0"] - G) <= 1e-9 * G
    assert abs(forces["table/collision0/ground"] - 3 * G) <= 1e-9 * 3 * G
    lying = can_scene([math.pi / 2, 0.0, 0.0], 0.15, [0.0, 0.0, -G], under=TABLE)
    run = simulate(lying, dt=0.1, duration=0.1, contacts="event")
    on_face = [e for e in run.info.contact_events if e["contact"].startswith("can/collision0/table")]
    assert [e["contact"][-3:] for e in on_face] == ["[0]", "[1]"]
    assert abs(sum(e["force"][0] for e in on_face) - G) <= 1e-9 * G


def test_two_round_shapes_are_refused_naming_them():
    ball = {"name": "ball", "shape": "sphere", "radius": 0.05, "mass": 1.0, "position": [0.0, 0.0, 0.5]}
    with pytest.raises(SceneError, match=r"'ball/collision0' and 'can/collision0' are both round.*cylinder"):
        can_scene([0.0, 0.0, 0.0], 0.1, [0.0, 0.0, -G], under=ball)


def test_box_stack_parameters_are_checked():
    with pytest.raises(SceneError, match=r"box-stack: parameter count must be an integer in \[1, 10\]"):
        load_scene("box-stack", count=0)
    with pytest.raises(SceneError, match=r"box-stack: parameter drop must be a number in \[-1, 1\] m"):
        load_scene("box-stack", drop=2.0)
