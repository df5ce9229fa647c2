"""allegro-drop (issue 36): the allegro-tilt grasp, its fingertips round pairs on the sphere and its hold relaxing once
let go, loses the sphere at the predicted slip; the sphere leaves the fingers, falls freely onto a level table at the
closed-form time of its flight, rolls on it against the table's rolling resistance at the closed-form deceleration and
comes to rest before t = 1 s; the same to the last bit each time."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from pinstab.grasp import tilt_at_first_slip
from pinstab.scene import load_scene
from pinstab.simulate import simulate

AXIS = np.array([-1.0, 0.0, 0.0])
FINGERS = {"index", "middle", "ring", "thumb"}
TABLE = "ball/collision0/ground[0]"


def world_velocity(q: np.ndarray, v: np.ndarray, at: int) -> np.ndarray:
    """The linear velocity [m/s, world] of the free flyer whose coordinates start at ``at`` (Pinocchio's is local)."""
    return pin.Quaternion(q[at + 3 : at + 7]).matrix() @ v[at : at + 3]


def test_the_sphere_leaves_the_hand_falls_onto_the_table_and_rolls_to_rest():
    scene = load_scene("allegro-drop")
    runs = [simulate(scene, contacts="event", duration=1.0, dt=0.01) for _ in range(2)]
    run, events = runs[0], runs[0].info.contact_events
    assert events == runs[1].info.contact_events  # deterministic: the same events and states to the last bit
    np.testing.assert_array_equal(runs[0].q, runs[1].q)
    np.testing.assert_array_equal(runs[0].v, runs[1].v)
    assert run.t[-1] == 1.0
    # the slip where the hold lets go: at allegro-tilt's predicted tilt, where index, middle and ring reach their
    # cones (the prediction's bisection is to 1e-6 deg, 5e-7 s)
    slips = [e for e in events if e["from"] == "sticking" and e["to"] in ("sliding", "separated")]
    tilt = load_scene("allegro-tilt")
    predicted = (math.radians(tilt_at_first_slip(tilt, AXIS)) - tilt.tilt.start) / tilt.tilt.rate
    assert abs(slips[0]["t"] - predicted) <= 1e-6
    hold = next(element for element in scene.forces if element.kind == "grasp-hold")
    assert abs(hold.released - slips[0]["t"]) <= 1e-9  # it let go there (measured 8e-13 s before the event)
    # every finger leaves the sphere, then the sphere lands on the table (one impact) and sticks there, rolling
    last = {e["contact"]: e for e in events}
    assert all(last[name]["to"] == "separated" for name in FINGERS)
    separated = max(last[name]["t"] for name in FINGERS)
    landing = [e for e in events if e["contact"] == TABLE and e["cause"] == "impact"]
    assert [e["to"] for e in landing] == ["closing", "sticking"] and landing[0]["t"] > separated
    stopped = (scene.tilt.stop - scene.tilt.start) / scene.tilt.rate  # [s]
    assert stopped < separated  # gravity stays from then on: the flight is a parabola
    # the flight: from each sample between the last separation and the landing, the closed-form parabola to the
    # table plane n . (x - p) = r gives the landing time (1e-6 s; measured 1.2e-11)
    ball = scene.objects[0].idx_q
    table = next(c for c in scene.constraints if c.name == TABLE)
    normal, point, radius = table.selection[0], table.plane_point, table.radius
    gravity = scene.tilt.gravity(separated)
    flight = np.flatnonzero((run.t > separated) & (run.t < landing[0]["t"]))
    assert flight.size >= 3
    for k in flight:
        height = float(normal @ (run.q[k, ball : ball + 3] - point)) - radius
        rate = float(normal @ world_velocity(run.q[k], run.v[k], ball))
        fall = -float(normal @ gravity)
        time = (rate + math.sqrt(rate * rate + 2.0 * fall * height)) / fall
        assert abs(run.t[k] + time - landing[0]["t"]) <= 1e-6
    # on the level table it rolls (the contact point sticks: omega x (-r n) = -v) against the table's rolling
    # resistance: the rolling torque at its bound rolling m g decelerates it at a = rolling g / (r (1 + 2/5)) (a solid
    # sphere) until its rolling stops (an event: rolling sticking), then it rests there
    rests = [e for e in events if e["contact"] == f"{TABLE} rolling" and e["to"] == "sticking"]
    assert len(rests) == 1 and rests[0]["cause"] == f"rolling slip reached zero at {TABLE}"
    rest = rests[0]["t"]
    assert landing[0]["t"] < rest < 1.0
    assert [e["to"] for e in events if e["contact"] == TABLE][-1] == "sticking"  # no slip on the table
    deceleration = table.rolling * float(np.linalg.norm(gravity)) / (radius * 1.4)
    rolling = np.flatnonzero((run.t > landing[0]["t"]) & (run.t < rest))
    for k in rolling:  # its speed a (rest - t) (1e-5 m/s of 0.32: the dense output of a turning body; measured 3e-7)
        assert abs(float(normal @ (run.q[k, ball : ball + 3] - point)) - radius) <= 1e-9
        speed = float(np.linalg.norm(world_velocity(run.q[k], run.v[k], ball)))
        assert abs(speed - deceleration * (rest - run.t[k])) <= 1e-5
        rotation = pin.Quaternion(run.q[k, ball + 3 : ball + 7]).matrix()
        spin = rotation @ run.v[k, ball + 3 : ball + 6]
        velocity = world_velocity(run.q[k], run.v[k], ball)
        np.testing.assert_allclose(np.cross(spin, -radius * normal), -velocity, atol=1e-9)
    at_rest = np.flatnonzero(run.t > rest)
    assert at_rest.size >= 3 and np.linalg.norm(world_velocity(run.q[-1], run.v[-1], ball)) < 1e-9
    centres = run.q[at_rest, ball : ball + 3]
    assert np.max(np.abs(centres - centres[-1])) <= 1e-10  # no creep while it rests
