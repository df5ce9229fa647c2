"""Impacts of event-driven contacts (issue 21, item 1, *closing*): Newton's restitution with Coulomb's law on
the round cone, every touching contact at once, against the closed forms of a rigid body's impacts."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

import pinstab.integration.events as events
from pinstab.constraints.contacts import contact_basis
from pinstab.errors import ContactInfeasibleError
from pinstab.generators import BOX_SIDE, incline
from pinstab.scene import scene_from_dict
from pinstab.simulate import simulate

G = 9.81
HALF = BOX_SIDE / 2
INERTIA = BOX_SIDE**2 / 6  # [kg m^2] the 1 kg cube's, about any axis through its centre


def box(restitution: float, mu: float, height: float, tilt: float = 0.0, vx: float = 0.0, corners: int = 4):
    """The incline's 1 kg cube on the level plane z = 0 (its contacts with ``restitution`` and ``mu``), turned by
    ``tilt`` [rad] about y, its lowest contact point ``height`` [m] above the plane, moving along x at ``vx``
    [m/s]. ``corners`` 1: its only contact is the middle of its lowest bottom edge (planar motion)."""
    data = incline(theta=0.0, mu=mu)
    if corners == 1:
        data["contacts"] = [{**data["contacts"][0], "name": "edge", "offset_a": [HALF, 0.0, -HALF]}]
    for contact in data["contacts"]:
        contact["restitution"] = restitution
    rotation = pin.utils.rotate("y", tilt)
    lowest = -min(float((rotation @ np.array(c["offset_a"]))[2]) for c in data["contacts"])
    quaternion = pin.Quaternion(rotation).coeffs()  # (x, y, z, w)
    data["initial"] = {
        "q": {"root_joint": [0.0, 0.0, height + lowest, *quaternion]},
        "v": {"root_joint": [*(rotation.T @ np.array([vx, 0.0, 0.0])), 0.0, 0.0, 0.0]},  # body axes
    }
    return scene_from_dict(data, "box-drop")


def world_velocity(scene, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cube's centre velocity [m/s] and angular velocity [rad/s] in world axes."""
    data = scene.model.createData()
    pin.forwardKinematics(scene.model, data, q, v)
    motion = pin.getVelocity(scene.model, data, 1, pin.LOCAL_WORLD_ALIGNED)
    return motion.linear, motion.angular


def impacts(run) -> list[dict]:
    return [event for event in run.info.contact_events if event["cause"] == "impact" and "impulse" in event]


@pytest.mark.parametrize("restitution", [0.0, 0.5])
def test_box_landing_flat_on_four_corners(restitution):
    """Dropped flat from h it lands at t0 = sqrt(2 h / g) with speed V = sqrt(2 g h) on its four corners at once:
    the normal impulses (not unique: redundant rows) sum to m (1 + e) V, no tangential impulse, no spin; then
    with e = 0 it rests (v = 0), with e = 0.5 it flies up at e V."""
    height, t_sample = 0.2, 0.25
    scene = box(restitution, 0.5, height)
    run = simulate(scene, dt=0.01, duration=t_sample, contacts="event")
    t0, speed = math.sqrt(2 * height / G), math.sqrt(2 * G * height)
    hits = impacts(run)
    assert sorted(e["contact"] for e in hits) == [f"corner{k}" for k in range(4)]
    assert max(abs(e["t"] - t0) for e in hits) <= 1e-10
    total = sum(e["impulse"][0] for e in hits)
    assert abs(total - (1 + restitution) * speed) <= 1e-8 * (1 + restitution) * speed
    assert max(abs(x) for e in hits for x in e["impulse"][1:]) <= 1e-10
    linear, angular = world_velocity(scene, run.q[-1], run.v[-1])
    if restitution == 0.0:
        np.testing.assert_allclose(run.v[-1], 0.0, atol=1e-9)
        assert {e["to"] for e in run.info.contact_events if e["t"] == hits[0]["t"] and e["from"] == "closing"} == {
            "sticking"
        }
    else:
        rising = restitution * speed - G * (t_sample - t0)
        assert abs(linear[2] - rising) <= 1e-9 * speed
        np.testing.assert_allclose([*linear[:2], *angular], 0.0, atol=1e-9)


def edge_impact(tilt: float, vx: float, speed: float, mu: float, e: float) -> tuple[np.ndarray, float]:
    """The closed-form impulse (P_x, P_z) [N s] and spin after it [rad/s] of the 1 kg cube turned by ``tilt``
    about y, its centre moving at (vx, 0, -speed) without spin, hitting z = 0 with the middle of its lowest
    bottom edge, arm r = R (h, 0, -h) from the centre. The point's velocity changes by K P, K = I/m + [r]^T
    [r] / J in the xz plane; sticking: K P = (-u_x, -(1 + e) u_z) when |P_x| <= mu P_z, else sliding:
    P_x = -mu P_z sign(u_x+) with the normal row of K P = -(1 + e) u_z (u_x+ keeps the sign of u_x here)."""
    rx, _, rz = pin.utils.rotate("y", tilt) @ np.array([HALF, 0.0, -HALF])
    k = np.eye(2) + np.array([[rz * rz, -rx * rz], [-rx * rz, rx * rx]]) / INERTIA
    u = np.array([vx, -speed])  # the point's velocity: no spin before
    impulse = np.linalg.solve(k, [-u[0], -(1 + e) * u[1]])
    if abs(impulse[0]) > mu * impulse[1]:
        sign = math.copysign(1.0, u[0])
        normal = -(1 + e) * u[1] / (k[1, 1] - mu * sign * k[1, 0])
        impulse = np.array([-mu * sign * normal, normal])
        assert (u + k @ impulse)[0] * sign > 0  # the slip keeps its direction: the law's premise
    return impulse, (rz * impulse[0] - rx * impulse[1]) / INERTIA


@pytest.mark.parametrize(("mu", "sticks"), [(0.8, True), (0.2, False)])
def test_tilted_box_edge_impact_as_the_closed_form(mu, sticks):
    """One contact, with friction and a horizontal velocity: a sticking impact (the contact point's tangential
    velocity after it is 0, the needed |P_t| / P_n = 0.56 <= mu = 0.8) and a sliding one (mu = 0.2: the
    impulse on the cone's edge). Sampled in the flight after the rebound (e = 0.5): the centre's velocity
    v+ + g (t - t0), the spin unchanged."""
    tilt, vx, drop, e, t_sample = 0.3, 1.0, 0.05, 0.5, 0.11
    scene = box(e, mu, drop, tilt, vx, corners=1)
    run = simulate(scene, dt=0.01, duration=t_sample, contacts="event")
    t0, speed = math.sqrt(2 * drop / G), math.sqrt(2 * G * drop)
    impulse, spin = edge_impact(tilt, vx, speed, mu, e)
    (hit,) = impacts(run)
    assert abs(hit["t"] - t0) <= 1e-10
    basis = contact_basis(np.array([0.0, 0.0, 1.0]))
    recorded = np.asarray(hit["impulse"]) @ basis  # world axes
    np.testing.assert_allclose(recorded, [impulse[0], 0.0, impulse[1]], rtol=0, atol=1e-9 * impulse[1])
    assert bool(abs(impulse[0]) < mu * impulse[1] * (1 - 1e-3)) is sticks
    linear, angular = world_velocity(scene, run.q[-1], run.v[-1])
    expected = [vx + impulse[0], 0.0, -speed + impulse[1] - G * (t_sample - t0)]
    np.testing.assert_allclose(linear, expected, rtol=0, atol=1e-9 * speed)
    np.testing.assert_allclose(angular, [0.0, spin, 0.0], rtol=0, atol=1e-9 * abs(spin))
    if sticks:  # the point's tangential velocity just after: 0
        rx, _, rz = pin.utils.rotate("y", tilt) @ np.array([HALF, 0.0, -HALF])
        assert abs(vx + impulse[0] + spin * rz) <= 1e-9 * vx


def test_impact_not_solved_is_named(monkeypatch):
    """ADMM stopped after one iteration on the four-corner landing: the run ends with an error naming them."""
    monkeypatch.setattr(events, "IMPACT_ITERATIONS", 1)
    with pytest.raises(ContactInfeasibleError, match="impact of contacts corner0, corner1, corner2, corner3"):
        simulate(box(0.0, 0.5, 0.2), dt=0.01, duration=0.25, contacts="event")


def test_box_tipping_onto_its_face_rocks_as_housner():
    """The cube at rest on its edge x = +h, turned by phi about y, tips over it (sticking, mu = 2) onto its
    face: at the landing, energy gives its spin w^2 = 2 m g h (sin phi + cos phi - 1) / J_edge (J_edge =
    J + 2 m h^2 = (2/3) m s^2) and its centre's velocity |w| (-h, 0, -h). The landing corners (e = 0) and the
    touching pivot corners solve one impact: Housner's rocking block, the spin about the new edge is
    1 - (3/2) sin^2(45 deg) = 1/4 of it (angular momentum about that edge), the centre's velocity
    |w| / 4 (-h, 0, h), the pivot lifts off without impulse: the impulses sum to m |w| h (3/4, 0, 5/4)."""
    tilt = 0.1
    scene = box(0.0, 2.0, 0.0, tilt)
    run = simulate(scene, dt=0.05, duration=0.06, contacts="event")
    assert not [e for e in run.info.contact_events if e["to"] == "sliding"]
    first = impacts(run)
    assert sorted(e["contact"] for e in first) == ["corner2", "corner3"]  # the pivot corner0, corner1: none
    spin = math.sqrt(2 * G * HALF * (math.sin(tilt) + math.cos(tilt) - 1) / (INERTIA + 2 * HALF**2))
    world = contact_basis(np.array([0.0, 0.0, 1.0]))
    total = np.sum([np.asarray(e["impulse"]) @ world for e in first], axis=0)
    np.testing.assert_allclose(total, spin * HALF * np.array([0.75, 0.0, 1.25]), rtol=0, atol=1e-8 * spin * HALF)
    lifted = {e["contact"] for e in run.info.contact_events if e["t"] == first[0]["t"] and e["to"] == "separated"}
    assert lifted == {"corner0", "corner1"}
