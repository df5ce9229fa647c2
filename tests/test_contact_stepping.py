"""Time-stepping contacts (issue 21, item 3) against closed forms and the event-driven contacts; the
painleve-rod scene (item 7) against its Painleve bound.

Measured (these tests): incline slide at 2 s relative error 1.0e-3, 5.0e-4, 2.5e-4 at dt = 2, 1, 0.5 ms
(order 1: semi-implicit Euler on a constant acceleration errs by exactly dt / t); sticking creep
3.1e-12 m over 10 s at dt = 1 ms; bouncing-ball apex gaps within 7.6e-4 m (k = 1..5, at most 1.08 v_k dt,
v_k the impact speed) and at rest 0.016 s after the closed-form rest time; sphere-spin v* 9.3e-14, 4.6e-14 relative at
dt = 1, 0.5 ms (exact but for rounding: the free flyer's translation stepped in world axes, no longer on the SE(3)
exponential's screw, which erred by 5.3e-2, 2.5e-2); painleve-rod below the bound within 9.1e-4 (dt = 1 ms) of the
event-driven run.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from pinstab.errors import PainleveError, PinstabError
from pinstab.generators import ROD_ANGLE, ROD_SPEED, box_stack
from pinstab.scene import load_scene, scene_from_dict
from pinstab.simulate import simulate

G = 9.81


def slide_error(dt: float) -> float:
    theta, mu = math.radians(30), 0.3
    run = simulate(load_scene("incline", theta=theta, mu=mu), dt=dt, duration=2.0, contacts="stepping")
    exact = G * (math.sin(theta) - mu * math.cos(theta)) * 2.0**2 / 2
    assert {e["to"] for e in run.info.contact_events} == {"sliding"}
    assert np.abs(run.q[:, 2] - 0.05).max() <= 1e-12  # no lift-off: the exact cone (NCP), not the convex one
    statistics = run.info.solver_statistics
    assert run.info.solver == "pinocchio-admm" and statistics.status_counts["ADMM converged"] == run.steps
    assert "ADMM not converged" not in statistics.status_counts
    assert statistics.worst_primal_residual <= 1e-10
    return (run.q[-1, 0] - exact) / exact


def test_incline_slide_converges_at_order_one_to_the_closed_form():
    errors = [slide_error(dt) for dt in (2e-3, 1e-3, 5e-4)]
    assert abs(errors[1]) <= 1e-3
    # semi-implicit Euler on a constant acceleration: x_k = a t^2 / 2 + a t dt / 2 exactly, relative error dt / t
    np.testing.assert_allclose(errors, [dt / 2.0 for dt in (2e-3, 1e-3, 5e-4)], rtol=1e-6)  # dt / t, t = 2 s
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    np.testing.assert_allclose(orders, 1.0, atol=1e-5)


def test_incline_sticks_below_the_friction_angle():
    theta, mu = math.radians(20), 0.37  # tan(20 deg) = 0.364
    run = simulate(load_scene("incline", theta=theta, mu=mu), dt=1e-3, duration=10.0, contacts="stepping")
    assert np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-10  # measured 3.1e-12 m
    assert [(e["to"], e["t"]) for e in run.info.contact_events] == [("sticking", 0.0)] * 4


def test_bouncing_ball_apexes_and_rest():
    height, e, radius, dt = 1.0, 0.5, 0.05, 1e-3
    run = simulate("bouncing-ball", dt=dt, duration=2.0, contacts="stepping")
    gap = run.q[:, 2] - radius
    apexes = [gap[k] for k in range(1, len(gap) - 1) if gap[k - 1] <= gap[k] > gap[k + 1] and gap[k] > 1e-6]
    k = np.arange(1, 6)
    exact = height * e ** (2 * k)
    impact_speeds = np.sqrt(2 * G * height * e ** (2 * (k - 1)))  # before the k-th rebound
    errors = np.abs(np.array(apexes[:5]) - exact)
    # the rebound starts up to a step's travel v_k dt above the plane, at the step's start speed (up to g dt
    # slower: the apex up to e v_k dt lower)
    assert np.all(errors <= (1 + e) * impact_speeds * dt)  # measured at most 1.08 v_k dt
    assert errors.max() <= 1e-3  # measured 7.6e-4 m
    impacts = [x for x in run.info.contact_events if x["from"] == "separated" and x["to"] != "separated"]
    assert len(impacts) >= 5 and all(x["impulse"][0] > 0 for x in impacts)
    rest = run.info.contact_events[-1]
    t_rest = math.sqrt(2 * height / G) * (1 + e) / (1 - e)
    assert rest["to"] == "sticking" and 0.0 <= rest["t"] - t_rest <= 0.02  # measured 0.016 s
    assert abs(gap[-1]) <= 1e-12 and np.abs(run.v[-1]).max() <= 1e-9  # at rest on the plane


def test_sphere_spin_rolls_at_the_closed_form_speed():
    v0, omega0, mu, radius = 2.0, 5.0, 0.3, 0.1
    scene = load_scene("sphere-spin")
    model = scene.model
    data = model.createData()
    rolling = (5 * v0 - 2 * radius * omega0) / 7
    t_star = 2 * (v0 + radius * omega0) / (7 * mu * G)
    errors = []
    for dt in (1e-3, 5e-4):
        run = simulate(scene, dt=dt, duration=1.0, contacts="stepping")
        switches = [(x["from"], x["to"]) for x in run.info.contact_events]
        assert switches == [("separated", "sliding"), ("sliding", "sticking")]
        assert abs(run.info.contact_events[1]["t"] - t_star) <= dt
        pin.forwardKinematics(model, data, run.q[-1], run.v[-1])
        speed = pin.getVelocity(model, data, 1, pin.LOCAL_WORLD_ALIGNED).linear[0]
        errors.append(abs(speed - rolling) / rolling)
    assert max(errors) <= 1e-10  # measured 9.3e-14, 4.6e-14: a constant acceleration, stepped exactly


def rod_delassus() -> np.ndarray:
    """The rod's end: its velocity change (x, z) per impulse (x, z) there [1/kg] (Newton and Euler, m = 1 kg,
    I = m L^2 / 12 about the centre, end at -l (cos theta, sin theta) from it)."""
    mass, half = 1.0, 0.5
    inertia = mass * (2 * half) ** 2 / 12
    c, s = math.cos(ROD_ANGLE), math.sin(ROD_ANGLE)
    # impulse (px, pz): dv_G = p / m, d omega = (r x p) / I with r = -l (c, s); dv_A = dv_G + d omega x r
    spin = np.array([half * s, -half * c]) / inertia  # d omega per (px, pz)
    return np.eye(2) / mass + np.outer([half * s, -half * c], spin)


def test_painleve_bound_is_the_event_dynamics():
    """N of the sliding mode at the start is m g / (1 + 3 cos theta (cos theta - mu sin theta)) (the
    generator's derivation), by the event dynamics (ModeDynamics) through event mode's first event."""
    for mu in (0.5, 1.3):
        run = simulate(load_scene("painleve-rod", mu=mu), dt=0.01, duration=0.01, contacts="event")
        first = run.info.contact_events[0]
        bracket = 1 + 3 * math.cos(ROD_ANGLE) * (math.cos(ROD_ANGLE) - mu * math.sin(ROD_ANGLE))
        assert first["to"] == "sliding"
        assert abs(first["force"][0] - G / bracket) <= 1e-9 * G / bracket
    assert abs((1 + 3 * math.cos(ROD_ANGLE) ** 2) / (3 * math.sin(ROD_ANGLE) * math.cos(ROD_ANGLE)) - 4 / 3) < 1e-15


@pytest.mark.parametrize("mu", [1.4, 2.0])
def test_painleve_rod_event_mode_names_the_paradox(mu):
    with pytest.raises(PainleveError, match="Painleve.*") as caught:
        simulate(load_scene("painleve-rod", mu=mu), dt=0.01, duration=0.1, contacts="event")
    assert caught.value.contacts == ["end"] and "end" in str(caught.value)


def test_painleve_rod_stepping_resolves_it_by_a_sticking_impulse():
    """Beyond the bound (mu = 2) the first step stops the sliding end dead: the impulse P is the plastic
    sticking impact's, W P = (v, g dt) (W: the end's Delassus matrix, closed form), inside the cone
    (|P_x| / P_z = 1.31 < mu); the rod then pivots on its end and swings up."""
    dt = 1e-3
    run = simulate(load_scene("painleve-rod", mu=2.0), dt=dt, duration=0.5, contacts="stepping")
    assert np.isfinite(run.q).all() and np.isfinite(run.v).all()
    first = run.info.contact_events[0]
    assert (first["from"], first["to"], first["cause"]) == ("separated", "sticking", "start")
    normal, _, along = first["impulse"]  # t2 is -x here: the slip velocity (0, 1) is the end moving along -x
    assert first["slip_velocity"][1] == pytest.approx(0.0, abs=1e-9)
    expected = np.linalg.solve(rod_delassus(), [ROD_SPEED, G * dt])
    np.testing.assert_allclose([-along, normal], expected, rtol=1e-9)
    assert abs(along) / normal < 2.0
    assert run.q[1, 2] > run.q[0, 2]  # the centre rises: the rod pivots up about its stopped end


def test_painleve_rod_below_the_bound_matches_event_mode():
    scene = load_scene("painleve-rod", mu=0.5)
    event = simulate(scene, dt=0.01, duration=0.5, contacts="event")
    errors = []
    for dt in (1e-3, 5e-4):
        stepping = simulate(scene, dt=dt, duration=0.5, contacts="stepping", record_every=round(0.01 / dt))
        errors.append(np.abs(stepping.q - event.q).max())
        assert [x["to"] for x in stepping.info.contact_events] == [x["to"] for x in event.info.contact_events]
    assert errors[0] <= 1e-3  # measured 9.1e-4
    assert 1.8 <= errors[0] / errors[1] <= 2.2  # order 1


def test_stepping_refuses_scenes_without_plane_contacts():
    with pytest.raises(PinstabError, match="plane contacts"):
        simulate("fourbar", dt=1e-3, duration=0.01, contacts="stepping")
    with pytest.raises(PinstabError, match="event, stepping"):
        simulate("incline", dt=1e-3, duration=0.01, contacts="steping")


def test_a_contact_that_the_others_impulses_close_is_in_the_problem():
    """Two stacked 1 kg cubes, the top one held up by half its weight: in free motion the bottom cube falls faster
    than the top one, so their contacts would open; the ground stops the bottom cube, and the top one, still falling
    at g / 2, closes on it. The problem takes those contacts too (solved again with them): the closed-form rest, both
    cubes still (1e-12 m, 1e-12 m/s), their gaps at zero to rounding (1e-10 m asserted; measured 5.5e-16 m; without
    it 7.4e-6 m, the top's corners chattering between sticking and separated, 276 events in 0.1 s), the normal
    forces the weights they carry (the top's m g / 2 on its corners, 3 m g / 2 on the ground, 1e-8 N; measured
    2.3e-10 N, ADMM's tolerance), and only the 12 events of the start (each contact's mode, recorded once)."""
    data = box_stack(2, 0.5)
    data["forces"] = [{"name": "lift", "kind": "external-force", "frame": "box1", "force": [0.0, 0.0, 0.5 * G]}]
    run = simulate(scene_from_dict(data, "lifted"), contacts="stepping", duration=0.1, dt=0.001)
    bottom, top = run.q[:, 2], run.q[:, 9]
    assert np.min(top - bottom - 0.1) >= -1e-10 and np.min(bottom - 0.05) >= -1e-10
    assert np.max(np.abs(run.q - run.q[0])) <= 1e-12 and np.max(np.abs(run.v)) <= 1e-12
    events = run.info.contact_events
    assert len(events) == 12 and all(event["cause"] == "start" for event in events)
    on_ground = sum(e["force"][0] for e in events if e["contact"].startswith("box0") and "ground" in e["contact"])
    on_bottom = sum(e["force"][0] for e in events if e["contact"].startswith("box0/collision0/box1"))
    assert abs(on_ground - 1.5 * G) <= 1e-8 and abs(on_bottom - 0.5 * G) <= 1e-8
