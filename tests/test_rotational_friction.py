"""Rotational friction at contacts (issue 36): torsion about the normal and rolling resistance about the tangents,
each bounded by its length [m] times the normal force, stick and slip in the event-driven modes, against closed
forms: a solid sphere (I = 2/5 m r^2) rolling to rest, spinning to rest, held or rolling on an incline; a pinch's
block spinning to rest between two fingers (torsion on planes carried by a body); a soft-finger grasp in event mode
against the same grasp held as constraint rows."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pinstab.errors import PinstabError, SceneError
from pinstab.generators import pinch, sphere_spin
from pinstab.integration.stepping import CHECK_STEPS
from pinstab.scene import load_scene, scene_from_dict
from pinstab.simulate import simulate
from pinstab.simulate.choice import MAX_EVENT_CONTACTS, contact_choice
from pinstab.simulate.contacts import contact_system
from pinstab.solvers.contact_modes import ModeDynamics
from pinstab.solvers.contact_states import contact_states
from pinstab.solvers.mode_choice import choose_modes
from pinstab.system import build_system

ROBOTS = Path(__file__).resolve().parents[1] / "robots"

G = 9.81
RADIUS = 0.1  # [m] the generator's 1 kg sphere
SHAPE = 1.0 + 2.0 / 5.0  # 1 + I / (m r^2), a solid sphere


def ball(v0: float = 0.0, spin: tuple[float, float, float] = (0.0, 0.0, 0.0), gravity=None, **friction) -> dict:
    """sphere-spin's 1 kg ball (r = 0.1 m) on the plane z = 0, mu 0.5, at v0 [m/s] along x with angular velocity
    ``spin`` [rad/s, world], the contact's rotational friction ``friction`` (torsion, rolling [m])."""
    scene = sphere_spin(v0=v0, omega0=0.0, mu=0.5, radius=RADIUS)
    scene["contacts"][0].update(friction)
    scene["initial"]["v"]["root_joint"] = [v0, 0.0, 0.0, *spin]
    if gravity is not None:
        scene["gravity"] = list(gravity)
    return scene


def world_velocity(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The free flyer's linear velocity [m/s, world] (Pinocchio's is in the body's axes)."""
    return pin.Quaternion(q[3:7]).matrix() @ v[:3]


def test_a_rolling_sphere_decelerates_at_the_closed_form_and_stops_for_good():
    """Rolling without slip, the rolling torque rolling * m g at its bound: m a = -f, I a / r = f r - rolling m g
    ... a = rolling g / (r (1 + I / (m r^2))), stopping at v0 / a; then static rolling friction holds it."""
    v0, rolling = 1.0, 0.003
    run = simulate(
        scene_from_dict(ball(v0, (0.0, v0 / RADIUS, 0.0), rolling=rolling)), dt=0.005, duration=5.8, contacts="event"
    )
    deceleration = rolling * G / (RADIUS * SHAPE)
    stop = v0 / deceleration  # 4.757 s
    events = run.info.contact_events
    rests = [e for e in events if e["contact"] == "ground rolling" and e["to"] == "sticking"]
    assert len(rests) == 1 and rests[0]["cause"] == "rolling slip reached zero at ground"
    assert abs(rests[0]["t"] - stop) <= 1e-8  # measured 2.7e-13 s
    assert {e["to"] for e in events if e["contact"] == "ground"} == {"sticking"}  # the point never slips
    expected = np.maximum(v0 - deceleration * run.t, 0.0)
    speeds = np.array([world_velocity(q, v)[0] for q, v in zip(run.q, run.v, strict=True)])
    # where steps end (every CHECK_STEPS-th sample): 1e-8 m/s (measured 4e-13); between, the dense output's
    # quartic interpolation of a turning free flyer: 1e-5 (measured 2.5e-6)
    ends = np.arange(0, run.t.size, CHECK_STEPS)
    assert np.max(np.abs(speeds[ends] - expected[ends])) <= 1e-8
    assert np.max(np.abs(speeds - expected)) <= 1e-5
    at_rest = np.flatnonzero(run.t >= stop)
    distance = v0 * v0 / (2 * deceleration)
    assert abs(run.q[at_rest[0], 0] - distance) <= 1e-7
    assert np.max(np.abs(run.q[at_rest, 0] - run.q[at_rest[-1], 0])) <= 1e-10  # no creep over 1 s at rest
    assert np.max(np.abs(run.v[-1])) <= 1e-10


def test_b_a_spinning_sphere_stops_at_the_torsion_closed_form():
    """Spinning about the vertical at w0: I_n w' = -torsion m g, stopping at w0 I_n / (torsion m g)."""
    w0, torsion = 5.0, 0.002
    run = simulate(scene_from_dict(ball(spin=(0.0, 0.0, w0), torsion=torsion)), dt=0.01, duration=2.0, contacts="event")
    rate = torsion * G / (0.4 * RADIUS**2)  # [rad/s^2], m = 1 kg
    stops = [e for e in run.info.contact_events if e["contact"] == "ground torsion" and e["to"] == "sticking"]
    assert len(stops) == 1 and abs(stops[0]["t"] - w0 / rate) <= 1e-8  # measured 2.3e-13 s
    # the spin about the vertical (a body axis, as the ball turns about it only): linear in t, then zero
    np.testing.assert_allclose(run.v[:, 5], np.maximum(w0 - rate * run.t, 0.0), rtol=0, atol=1e-8)
    later = run.t >= stops[0]["t"]
    assert np.max(np.abs(run.v[later, 5])) <= 1e-10 and np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-12


@pytest.mark.parametrize("factor", [1.1, 0.9])
def test_c_on_an_incline_rolling_resistance_holds_or_slows_the_ball(factor):
    """On an incline of angle th (gravity turned by th) the ball at rest stays iff rolling >= r tan(th) (the
    rolling torque holds the friction's moment f r = m g sin(th) r, its bound rolling m g cos(th)); below, it rolls
    with a = g (sin(th) - rolling cos(th) / r) / (1 + I / (m r^2))."""
    theta = 0.1
    rolling = factor * RADIUS * math.tan(theta)
    gravity = (G * math.sin(theta), 0.0, -G * math.cos(theta))
    run = simulate(scene_from_dict(ball(gravity=gravity, rolling=rolling)), dt=0.01, duration=1.0, contacts="event")
    spins = [e for e in run.info.contact_events if e["contact"] == "ground rolling"]
    if factor > 1.0:
        assert [e["to"] for e in spins] == ["sticking"]
        assert np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-12
        return
    assert [e["to"] for e in spins] == ["sliding"]
    acceleration = G * (math.sin(theta) - rolling * math.cos(theta) / RADIUS) / SHAPE
    ends = np.arange(0, run.t.size, CHECK_STEPS)
    np.testing.assert_allclose(run.q[ends, 0], acceleration * run.t[ends] ** 2 / 2, rtol=0, atol=1e-10)
    speeds = np.array([world_velocity(q, v)[0] for q, v in zip(run.q[ends], run.v[ends], strict=True)])
    np.testing.assert_allclose(speeds, acceleration * run.t[ends], rtol=0, atol=1e-10)


def test_torsion_on_planes_carried_by_a_body_stops_a_pinched_block():
    """pinch's block (I_x = m s^2 / 6) spinning at w0 about the pinch axis between two fingers pressing with F each,
    torsion at both contacts (their planes carried by the block): I_x w' = -2 torsion F, stopping at
    w0 I_x / (2 torsion F); friction holds the block's weight (2 mu F >= m g) throughout."""
    w0, torsion, squeeze, mass, side = 5.0, 0.001, 1.0, 0.1, 0.05
    scene = pinch(mu=0.5, squeeze=squeeze, mass=mass)
    for contact in scene["contacts"]:
        contact["torsion"] = torsion
    scene["initial"]["v"] = {"block": [0.0, 0.0, 0.0, w0, 0.0, 0.0]}
    run = simulate(scene_from_dict(scene), dt=0.01, duration=0.3, contacts="event")
    rate = 2 * torsion * squeeze / (mass * side**2 / 6)
    stops = [e for e in run.info.contact_events if e["contact"].endswith("torsion") and e["to"] == "sticking"]
    assert {e["contact"] for e in stops} == {"left torsion", "right torsion"}
    assert all(abs(e["t"] - w0 / rate) <= 1e-8 for e in stops)  # measured 1.1e-14 s
    np.testing.assert_allclose(run.v[:, 3], np.maximum(w0 - rate * run.t, 0.0), rtol=0, atol=1e-8)
    assert np.max(np.abs(run.q[:, :3])) <= 1e-12  # the block neither slides nor falls


def soft_finger_scene(tmp_path, torsion: str):
    """allegro-sphere with soft-finger contacts of ``torsion``."""
    text = (ROBOTS / "allegro-sphere.toml").read_text()
    path = tmp_path / "allegro-soft.toml"
    path.write_text(text.replace('model = "point-friction"', f'model = "soft-finger"\ntorsion = "{torsion}"'))
    return load_scene(path)


def test_d_a_soft_finger_grasp_runs_in_event_mode_and_holds_the_spin(tmp_path):
    """allegro-sphere's grasp with soft fingers (torsion 20 mm: every spin sticks) in event mode: at the start its
    accelerations are those of the same grasp held as constraint rows (a second method: 4 rows per soft finger; 1.6e-12
    of 12 rad/s^2 measured), not the point contacts' (which differ by 9.7); over the run each finger's spin about its
    normal relative to the ball stays at zero (the point contacts' reaches 1e-4 rad/s)."""
    scene = soft_finger_scene(tmp_path, "20 mm")
    start = np.zeros(scene.model.nv)
    held = build_system(scene).dynamics(scene.q0, start, 0.0, 0).acceleration
    accelerations = {}
    for name, grasp in (("soft", scene), ("point", load_scene("allegro-sphere"))):
        geometries, system, q, v, _ = contact_system(grasp, grasp.q0, start)
        accelerations[name] = choose_modes(ModeDynamics(system.model, geometries), q, v, 0.0).solution.acceleration
    assert np.max(np.abs(accelerations["soft"] - held)) <= 1e-9 * np.max(np.abs(held))
    assert np.max(np.abs(accelerations["point"] - held)) >= 1.0
    geometries, system, _, _, _ = contact_system(scene, scene.q0, start)
    dynamics = ModeDynamics(system.model, geometries)
    spins = {}
    for name, grasp in (("soft", scene), ("point", load_scene("allegro-sphere"))):
        run = simulate(grasp, dt=0.01, duration=0.1, contacts="event")
        assert {e["to"] for e in run.info.contact_events} == {"sticking"}
        spins[name] = max(np.max(np.abs(dynamics.kinematics(q, v).spins)) for q, v in zip(run.q, run.v, strict=True))
    assert spins["soft"] <= 1e-8 and spins["point"] >= 1e-5  # measured 2.9e-9, 1.4e-4 rad/s


def test_d_a_soft_finger_slips_in_torsion_at_its_bound(tmp_path):
    """With torsion 5 mm the ring finger's spin slips from the start: its torque on the bound torsion f_n,
    opposing its spin's acceleration; the others' inside theirs; the slip stops later and sticks (an event)."""
    torsion = 0.005
    run = simulate(soft_finger_scene(tmp_path, "5 mm"), dt=0.01, duration=0.1, contacts="event")
    events = [e for e in run.info.contact_events if e["contact"].endswith("torsion")]
    starts = {e["contact"]: e for e in events if e["cause"] == "start"}
    assert [name for name, e in starts.items() if e["to"] == "sliding"] == ["ring torsion"]
    for e in starts.values():
        normal, torque = e["force"][0], e["force"][1]
        bound = torsion * normal
        assert (abs(abs(torque) - bound) <= 1e-12 * bound) if e["to"] == "sliding" else abs(torque) < bound
    # the middle finger's spin reaches its bound (its torque there on it), the ring's slip stops, then the middle's
    later = [(e["contact"], e["from"], e["to"], e["cause"]) for e in events if e["cause"] != "start"]
    assert later == [
        ("middle torsion", "sticking", "sliding", "torsion reached its bound at middle"),
        ("ring torsion", "sliding", "sticking", "torsion slip reached zero at ring"),
        ("middle torsion", "sliding", "sticking", "torsion slip reached zero at middle"),
    ]
    reached = next(e for e in events if e["cause"] == "torsion reached its bound at middle")
    assert abs(abs(reached["force"][1]) - torsion * reached["force"][0]) <= 1e-12 * reached["force"][0]
    # a spin that slips from rest is a slip for stop_on, as a contact's is: the ring's at the start
    stopped = simulate(soft_finger_scene(tmp_path, "5 mm"), dt=0.01, duration=0.1, contacts="event", stop_on="slip")
    assert (stopped.info.stopped["contact"], stopped.info.stopped["t"]) == ("ring torsion", 0.0)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"rolling": -0.001}, r"contact 'ground'\.rolling must be a length >= 0 \[m\]"),
        ({"torsion": "abc"}, r"contact 'ground'\.torsion: cannot read 'abc'"),
        ({"rolling": True}, r"contact 'ground'\.rolling: expected a number"),
        ({"torsion": float("nan")}, r"contact 'ground'\.torsion: value nan is not finite"),
        ({"rolling": "3 kg"}, r"contact 'ground'\.rolling: unit 'kg' is not a unit of length"),
        ({"rolling": 0.003, "mu": None}, r"contact 'ground'\.rolling: rotational friction acts on a contact with "),
    ],
)
def test_invalid_rotational_friction_is_refused_by_name(extra, message):
    """Negative, non-numeric, non-finite, not a length, or on a frictionless contact (``mu`` None: dropped)."""
    scene = ball()
    contact = {**scene["contacts"][0], **extra}
    scene["contacts"][0] = {key: value for key, value in contact.items() if value is not None}
    with pytest.raises(SceneError, match=message):
        scene_from_dict(scene)


def test_geometry_contacts_take_rotational_friction_and_refuse_it_without_friction():
    scene = ball()
    scene["contacts"] = [{"kind": "geometry", "mu": 0.5, "rolling": "3 mm", "torsion": "1 mm"}]
    found = scene_from_dict(scene).constraints
    assert found and all((c.rolling, c.torsion) == (0.003, 0.001) for c in found)
    scene["contacts"] = [{"kind": "geometry", "rolling": "3 mm"}]
    with pytest.raises(SceneError, match=r"'contact0'\.rolling: rotational friction acts on a contact with friction"):
        scene_from_dict(scene)


def test_time_stepping_contacts_refuse_rolling_resistance_by_name():
    with pytest.raises(
        PinstabError, match=r"time-stepping contacts have no rolling resistance yet \(they take torsion\) at ground;"
    ):
        simulate(scene_from_dict(ball(rolling=0.003)), dt=0.01, duration=0.1, contacts="stepping")


def test_contact_states_replay_the_spins_modes():
    """contact_states of the rolling ball: the rolling spin's modes from its events, the table's force m g up and
    -m a along the motion while it rolls against the rolling torque (Newton: the only horizontal force), 0 at rest."""
    v0, rolling = 0.2, 0.003
    scene = scene_from_dict(ball(v0, (0.0, v0 / RADIUS, 0.0), rolling=rolling))
    run = simulate(scene, dt=0.01, duration=1.5, contacts="event")
    states = contact_states(scene, run)
    deceleration = rolling * G / (RADIUS * SHAPE)
    rolls = run.t < v0 / deceleration - 0.01
    np.testing.assert_allclose(states.forces[:, 0, 2], G, rtol=0, atol=1e-9)
    np.testing.assert_allclose(states.forces[rolls, 0, 0], -deceleration, rtol=0, atol=1e-9)
    np.testing.assert_allclose(states.forces[run.t > v0 / deceleration, 0, :2], 0.0, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    ("friction", "treatment"),
    [({"rolling": 0.003}, "event"), ({"rolling": 0.0}, "stepping"), ({"torsion": 0.002}, "stepping")],
)
def test_many_contacts_with_rolling_resistance_default_to_event_driven(friction, treatment):
    """Beyond MAX_EVENT_CONTACTS declared contacts the automatic choice is time-stepping, which takes torsion but has
    no rolling resistance: with rolling, event-driven."""
    scene = ball()
    contact = {**scene["contacts"][0], **friction}
    scene["contacts"] = [{**contact, "name": f"ground{k}"} for k in range(MAX_EVENT_CONTACTS + 1)]
    assert contact_choice(scene_from_dict(scene)).treatment == treatment
