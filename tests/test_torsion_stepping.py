"""Torsion (soft-finger friction) in time-stepping contacts (issue 36; cpp/torsion_cone.hpp, the contact problem with a
fourth row per contact with torsion): against closed forms (a ball and a box spinning to rest, a twist held below the
bound and spun up above it), against the same scenes in event-driven contacts, and the compiled step against the
NumPy reference step (pinstab/bench/python_stepper.py, whose torsion solve is pinstab/bench/torsion_admm.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pinstab.bench.python_stepper import PythonStepper
from pinstab.bench.torsion_admm import projection, torsion_admm
from pinstab.generators import box_stack, sphere_spin
from pinstab.scene import load_scene, scene_from_dict
from pinstab.simulate import simulate
from pinstab.simulate.contacts import stepping_parts
from pinstab.simulate.loop import start_state
from pinstab.solvers.ncp import CHECK_RTOL, NcpSolver, ncp_residual

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
G = 9.81
RADIUS, MASS = 0.1, 1.0  # sphere-spin's ball: I = 2/5 m r^2 about every axis
BALL_INERTIA = 0.4 * MASS * RADIUS**2  # [kg m^2]
BOX_SIDE = 0.1  # box-stack's 1 kg cube: I_z = m (2 s^2) / 12, corners at s / sqrt(2) from the vertical axis
BOX_INERTIA = MASS * 2 * BOX_SIDE**2 / 12
CORNER = BOX_SIDE / math.sqrt(2)
DT = 1e-3  # [s]


def ball(torsion: float, v0: float = 0.0, spin: float = 0.0, moment: float = 0.0) -> dict:
    """sphere-spin's ball on z = 0 (mu 0.5) with ``torsion`` [m], sliding at v0 [m/s] along x and spinning at
    ``spin`` [rad/s] about the vertical, twisted by a constant ``moment`` [N m] about it."""
    scene = sphere_spin(v0=v0, omega0=0.0, mu=0.5, radius=RADIUS)
    scene["contacts"][0]["torsion"] = torsion
    scene["initial"]["v"]["root_joint"] = [v0, 0.0, 0.0, 0.0, 0.0, spin]
    if moment:
        scene["forces"] = [{"name": "twist", "kind": "external-force", "frame": "ball", "moment": [0.0, 0.0, moment]}]
    return scene


def box(torsion: float, spin: float, mu: float = 0.5) -> dict:
    """box-stack's single cube on its four corners (found from geometry, friction mu) with ``torsion`` [m] at each,
    spinning at ``spin`` [rad/s] about the vertical."""
    scene = box_stack(count=1, mu=mu)
    scene["contacts"][0]["torsion"] = torsion
    scene["initial"] = {"v": {"box0": [0.0, 0.0, 0.0, 0.0, 0.0, spin]}}
    return scene


def stops(run, suffix: str = "torsion") -> list[float]:
    """The times [s] of the run's torsions coming to rest (events sliding -> sticking)."""
    events = run.info.contact_events
    return [e["t"] for e in events if e["contact"].endswith(suffix) and (e["from"], e["to"]) == ("sliding", "sticking")]


@pytest.mark.parametrize("contacts", ["stepping", "event"])
def test_a_spinning_ball_decelerates_at_the_closed_form_and_stops(contacts):
    """I w' = -torsion m g while it spins, w = 0 from t* = w0 I / (torsion m g) = 1.0194 s: time-stepping takes the
    torque impulse torsion m g dt each step (the normal impulse is m g dt) and stops in the step holding t*; its spin
    is the closed form's to 1e-9 rad/s at every step (measured 2.1e-12), the event-driven run's too (2.2e-12); after
    the stop it stays below 1e-10 rad/s (measured 0 and 2.2e-12)."""
    w0, torsion = 5.0, 0.002
    run = simulate(scene_from_dict(ball(torsion, spin=w0)), dt=DT, duration=1.2, contacts=contacts)
    rate = torsion * MASS * G / BALL_INERTIA
    stop = w0 / rate
    np.testing.assert_allclose(run.v[:, 5], np.maximum(w0 - rate * run.t, 0.0), rtol=0, atol=1e-9)
    (t_stop,) = stops(run)
    assert (0.0 <= t_stop - stop < DT) if contacts == "stepping" else abs(t_stop - stop) <= 1e-8
    assert np.max(np.abs(run.v[run.t > t_stop, 5])) <= 1e-10  # stuck for good
    assert np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-12  # it spins in place


def test_a_box_spinning_on_four_corners_stops_at_the_closed_form_in_both_treatments():
    """A cube spinning on its four corners: each corner slides on its circle, I_z w' = -(mu r_c + torsion) m g
    whatever the split of the weight among the corners (a redundant set); the stepping run's spin is the closed form's
    to 1e-8 rad/s (measured 2.6e-10: ADMM's tolerance through 4 redundant contacts; the event run's 1.6e-10), every
    corner's torsion stops in the step holding t* = 0.0421 s, the event run's at t* (1e-8 s; measured 7e-13), and
    neither moves the cube's centre."""
    w0, torsion, mu = 10.0, 0.005, 0.5
    rate = (mu * CORNER + torsion) * MASS * G / BOX_INERTIA
    stop = w0 / rate
    for contacts in ("stepping", "event"):
        run = simulate(scene_from_dict(box(torsion, w0, mu)), dt=DT, duration=0.06, contacts=contacts)
        np.testing.assert_allclose(run.v[:, 5], np.maximum(w0 - rate * run.t, 0.0), rtol=0, atol=1e-8)
        ends = stops(run)
        assert len(ends) == 4
        for t_stop in ends:
            assert (0.0 <= t_stop - stop < DT) if contacts == "stepping" else abs(t_stop - stop) <= 1e-8
        assert np.max(np.abs(run.q[:, :3] - run.q[0, :3])) <= 1e-12


@pytest.mark.parametrize("factor", [0.9, 0.999, 1.1])
def test_a_twist_below_the_bound_is_held_and_above_it_spins_the_ball_up(factor):
    """A constant moment M = factor torsion m g about the vertical on the ball at rest: below the bound the torsion
    sticks (spin 0 to 1e-12 rad/s, measured 3.3e-15 at 0.9 and 1.2e-15 at 0.999 of the bound); above it the ball
    spins up at (M - torsion m g) / I, the torsion sliding at its bound (1e-9 rad/s, measured 2.8e-14)."""
    torsion = 0.002
    bound = torsion * MASS * G
    run = simulate(scene_from_dict(ball(torsion, moment=factor * bound)), dt=DT, duration=0.5, contacts="stepping")
    rate = max(factor * bound - bound, 0.0) / BALL_INERTIA
    np.testing.assert_allclose(run.v[:, 5], rate * run.t, rtol=0, atol=1e-12 if factor < 1.0 else 1e-9)
    modes = [e["to"] for e in run.info.contact_events if e["contact"] == "ground torsion"]
    assert modes == (["sticking"] if factor < 1.0 else ["sliding"])


def reference_pair(scene: dict) -> tuple:
    """The compiled and the NumPy stepper of ``scene`` and its start state."""
    compiled_scene, reference_scene = scene_from_dict(scene), scene_from_dict(scene)
    _, compiled, q, v = stepping_parts(compiled_scene, DT, *start_state(compiled_scene, None, None))
    start = start_state(reference_scene, None, None)
    _, reference, _, _ = stepping_parts(reference_scene, DT, *start, PythonStepper)
    return compiled, reference, q, v


@pytest.mark.parametrize(
    ("scene", "steps"),
    [
        (ball(0.002, v0=0.3, spin=0.3), 100),  # slides and spins; rolls from 0.0175 s, spins until 0.061 s
        (ball(0.2, v0=0.3, spin=5.0), 30),  # a torsion of 20 cm (steep once scaled): the spin stops at 0.011 s
        (box(0.005, 10.0), 80),  # four redundant corners, each sliding and spinning, stopping at 0.0421 s
    ],
    ids=["ball", "ball-steep-torsion", "box"],
)
def test_each_compiled_torsion_step_is_the_numpy_step(scene, steps):
    """From the compiled run's state at every step both steppers step: the same end state to 1e-11, the same modes of
    the contacts and their torsions, the same impulses and torque impulses to 1e-12 (measured: states 7.8e-16, 6.6e-12,
    2.0e-15; impulses below 2e-16: the same iteration to the same stop, in other orders of sums; the steep torsion's
    spin of 5 rad/s is solved again from the midpoint of its answer until the free velocity moves by at most
    IMPULSE_TOLERANCE, 1e-12 of the velocities: the two steps may stop a pass apart)."""
    compiled, reference, q, v = reference_pair(scene)
    worst, seen = 0.0, set()
    for k in range(steps):
        expected = reference.step(q.copy(), v.copy(), k * DT, DT)
        q, v = compiled.step(q, v, k * DT, DT)
        worst = max(worst, float(np.max(np.abs(q - expected[0]))), float(np.max(np.abs(v - expected[1]))))
        assert (compiled.modes, compiled.spin_modes) == (reference.modes, reference.spin_modes), k
        np.testing.assert_allclose(compiled.impulses, reference.impulses, rtol=0, atol=1e-12)
        np.testing.assert_allclose(compiled.torques, reference.torques, rtol=0, atol=1e-12)
        seen.update(compiled.spin_modes)
    assert worst <= 1e-11, worst
    assert {m.value for m in seen} == {"sliding", "sticking"}  # the runs spin to rest


def single_contact(mu: float, torsion: float, spin: float) -> tuple[np.ndarray, np.ndarray]:
    """A contact pressed at normal velocity -1 m/s with a spin [rad/s] about its normal and no slip, rows (t1, t2, n,
    tau) decoupled (D = diag(2, 2, 1, 50)): its law's answer is lambda_n = 1, lambda_t = 0, lambda_tau = -spin / 50
    while that is within torsion, else -torsion sign(spin)."""
    return np.diag([2.0, 2.0, 1.0, 50.0]), np.array([0.0, 0.0, -1.0, spin])


@pytest.mark.parametrize("spin", [0.05, -0.05, 0.2, -3.0])
def test_the_compiled_and_numpy_torsion_solves_meet_the_closed_form(spin):
    """Both solves (ConeSolver.solve_torsion, torsion_admm) on the decoupled single contact: its closed form to 1e-11
    (ADMM stops at 1e-12 of the velocity scale: measured 2.3e-12),
    each accepted by ncp_residual, whose value at a torque 1e-3 N m s off the answer is no longer within the check."""
    torsion = 0.002
    delassus, g = single_contact(0.5, torsion, spin)
    expected = np.array([0.0, 0.0, 1.0, -math.copysign(min(abs(spin) / 50.0, torsion), spin)])
    solver = NcpSolver(3)
    compiled = solver.cones.solve_torsion(delassus, g, np.array([0.5]), np.array([torsion]), CHECK_RTOL)
    numpy_answer, _ = torsion_admm(delassus, g, [0.5], [torsion], 1e-12, 10_000)
    for answer in (compiled, numpy_answer):
        np.testing.assert_allclose(answer, expected, rtol=0, atol=1e-11)
        assert ncp_residual(delassus, g, answer, [0.5], [torsion]) <= 1e-11
    off = expected + np.array([0.0, 0.0, 0.0, 1e-3])
    assert ncp_residual(delassus, g, off, [0.5], [torsion]) > CHECK_RTOL * 50.0


def test_the_projection_is_the_nearest_point_of_the_set():
    """Moreau's decomposition x = P(x) - q with P(x) in K, q in K* = {q_n >= mu |q_t| + torsion |q_tau|} and P(x) . q
    = 0 (characterizes the projection onto a closed convex cone), over 20,000 seeded points of every scale: within
    1e-12 of |x|."""
    rng = np.random.default_rng(36)
    worst = 0.0
    for _ in range(20_000):
        x = rng.normal(size=4) * rng.choice([1e-3, 1.0, 1e3], size=4)
        mu, torsion = rng.choice([0.0, 0.3, 1.0, 4.0]), rng.choice([0.0, 0.002, 0.5, 3.0])
        x[3] *= torsion > 0.0
        p = projection(x, mu, torsion)
        q = p - x
        size = float(np.max(np.abs(x)))
        inside = max(math.hypot(p[0], p[1]) - mu * p[2], abs(p[3]) - torsion * p[2], -p[2])
        dual = mu * math.hypot(q[0], q[1]) + torsion * abs(q[3]) - q[2]
        worst = max(worst, inside / size, dual / size, abs(p @ q) / size**2)
    assert worst <= 1e-12


def test_a_soft_finger_grasp_steps_through_the_event_runs_torsion_events(tmp_path):
    """allegro-sphere with soft fingers of torsion 5 mm (the ring finger's spin slips from the start): time-stepping
    (1 ms) has the event-driven run's torsion events, the same fingers in the same order with the same modes, each
    within a step of the event's time (measured: 0.022, 0.047, 0.077 s against 0.02142, 0.04736, 0.07638 s: the
    stepped motion is the event run's to first order in dt),
    and ends within 1e-4 rad of its joint positions (measured 5.7e-5: first order in dt, 1.3e-5 at 0.25 ms)."""
    text = (ROBOTS / "allegro-sphere.toml").read_text()
    path = tmp_path / "allegro-soft.toml"
    path.write_text(text.replace('model = "point-friction"', 'model = "soft-finger"\ntorsion = "5 mm"'))
    runs = {
        contacts: simulate(load_scene(path), dt=dt, duration=0.1, contacts=contacts)
        for contacts, dt in (("event", 0.01), ("stepping", DT))
    }
    switches = {
        contacts: [
            (e["t"], e["contact"], e["from"], e["to"])
            for e in run.info.contact_events
            if e["contact"].endswith("torsion")
        ]
        for contacts, run in runs.items()
    }
    assert [s[1:] for s in switches["stepping"]] == [s[1:] for s in switches["event"]]
    assert len(switches["event"]) == 7  # four at the start, then three
    for (t_step, *_), (t_event, *_) in zip(switches["stepping"][4:], switches["event"][4:], strict=True):
        assert abs(t_step - t_event) < DT
    assert np.max(np.abs(runs["stepping"].q[-1] - runs["event"].q[-1])) <= 1e-4
