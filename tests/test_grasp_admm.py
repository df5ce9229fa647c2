"""Pinocchio 4.1's own contact solver (ADMM on Coulomb cones, ``pinstab.bench.admm_peer``) against
pinstab's grasp-contact multipliers on ``allegro-sphere``, and the peer itself against closed forms on
the box of test_contacts (sticking and sliding).

ADMM runs at 1e-12 absolute and relative feasibility and complementarity tolerances; forces are
compared to 1e-9 N (normal forces 1.5 to 2.5 N). Both sides solve the same rows with the same
right-hand side: the drift alone for pinstab's ``none``, drift + Kd J v + Kp e for ``baumgarte`` (the
peer is given pinstab's gains; Pinocchio's residual e is pinstab's row up to a fixed rotation)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_contacts import GRAVITY, MASS, MU, box_scene

from pinstab import ConstrainedModel, PinstabError, assemble, load_scene, simulate
from pinstab.bench.admm_peer import AdmmContactPeer, PeerForces, PeerSettings, run_peer
from pinstab.system import build_system

TOLERANCE = 1e-12  # ADMM's feasibility and complementarity tolerances
RESIDUAL = 1e-11  # ADMM's residuals where it stops (its test adds relative terms: 1e-12 x the largest entry)
AGREEMENT = 1e-9  # [N]
GAINS = {"none": (0.0, 0.0), "baumgarte": (100.0, 20.0)}  # (Kp [1/s^2], Kd [1/s]) of the rhs


@pytest.fixture(scope="module")
def hand():
    """(allegro-sphere, its ConstrainedModel, the assembled start)."""
    scene = load_scene("allegro-sphere")
    model = ConstrainedModel(scene)
    return scene, model, assemble(model, scene.q0, scene.v0)


def applied(model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
    """pinstab's applied generalized forces (grasp hold + push) at (q, v, t) [N, N m]."""
    model.kin.update(q, v)
    return model.applied_force(v, t)


def assert_converged(solution) -> None:
    assert solution.converged
    assert max(solution.primal_feasibility, solution.dual_feasibility, solution.complementarity) <= RESIDUAL


def test_admm_finds_pinstabs_grasp_forces_at_the_assembled_start(hand):
    """At rest the rhs is the drift alone (e = 0, J v = 0): ADMM's forces, cone-constrained, are the
    ones pinstab's equality rows give, inside every cone, and with ADMM's acceleration of the ball they
    satisfy Newton's law for it: sum of the fingers' forces (world axes) = m a - m g - push."""
    scene, model, start = hand
    peer = AdmmContactPeer(scene, TOLERANCE)
    solution = peer.solve(start.q, start.v, applied(model, start.q, start.v, 0.0))
    assert_converged(solution)
    expected = build_system(scene, "none", "proxsuite").dynamics(start.q, start.v, 0.0).multipliers
    np.testing.assert_allclose(solution.forces, expected, rtol=0, atol=AGREEMENT)
    for force in solution.by_contact().values():
        assert force[2] > 1.0 and np.hypot(force[0], force[1]) < 0.8 * force[2]
    ball = scene.objects[0]
    first = scene.model.joints[ball.joint].idx_v  # the ball's body twist (linear first); its frame is world-aligned
    assert np.allclose(ball.placement.rotation, np.eye(3))
    newton = ball.mass * (solution.motion[first : first + 3] + [0.0, 0.0, 9.81]) - [0.0, 0.2, 0.0]
    np.testing.assert_allclose(peer.world_forces(solution).sum(axis=0), newton, rtol=0, atol=1e-9)
    assert np.linalg.norm(solution.motion[first : first + 3]) > 0.1  # the push accelerates the ball


@pytest.mark.parametrize("method", ["none", "baumgarte"])
def test_admm_finds_pinstabs_multipliers_along_a_run(hand, method):
    """Samples every 50 ms of a 0.5 s run (RK4, 1 ms; the push sets the grasp moving, |v| up to
    0.2 rad/s): ``trajectory.multipliers`` equal ADMM's forces with the run's rhs."""
    scene, model, _ = hand
    trajectory = simulate(scene, method, "rk4", 1e-3, 0.5, record_every=50)
    assert len(trajectory.t) == 11 and np.abs(trajectory.v).max() > 0.1
    peer = AdmmContactPeer(scene, TOLERANCE)
    kp, kd = GAINS[method]
    for t, q, v, multipliers in zip(trajectory.t, trajectory.q, trajectory.v, trajectory.multipliers, strict=True):
        solution = peer.solve(q, v, applied(model, q, v, float(t)), kp, kd)
        assert_converged(solution)
        np.testing.assert_allclose(solution.forces, multipliers, rtol=0, atol=AGREEMENT)


def off_the_grasp(scene, start, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """A state a fixed random step of ``scale`` [rad, m] away from the start, with velocities 100 times
    that per second: the fingertips leave the ball's material points."""
    rng = np.random.default_rng(7)
    q = pin.integrate(scene.model, start.q, scale * rng.standard_normal(scene.model.nv))
    return q, 100.0 * scale * rng.standard_normal(scene.model.nv)


@pytest.mark.parametrize("method", ["none", "baumgarte"])
def test_the_rows_are_the_same_off_the_grasp(hand, method):
    """1e-3 away from the grasp (fingertips 2.4 mm off their points on the ball, rows' rates 0.06 m/s):
    pinstab's multipliers with the method's rhs equal ADMM's with the same one, and differ from ADMM's
    with the other one by more than 0.01 N (the comparison resolves the Baumgarte term)."""
    scene, model, start = hand
    q, v = off_the_grasp(scene, start, 1e-3)
    expected = build_system(scene, method, "proxsuite").dynamics(q, v, 0.0).multipliers
    peer = AdmmContactPeer(scene, TOLERANCE)
    tau = applied(model, q, v, 0.0)
    solution = peer.solve(q, v, tau, *GAINS[method])
    assert_converged(solution)
    np.testing.assert_allclose(solution.forces, expected, rtol=0, atol=AGREEMENT)
    other = GAINS["baumgarte" if method == "none" else "none"]
    assert np.abs(peer.solve(q, v, tau, *other).forces - expected).max() > 0.01


def test_peer_applies_the_scenes_hold_and_push(hand):
    """The peer's own hold torques and push (from its Pinocchio pass and contact Jacobian) equal
    pinstab's force elements, off the grasp too."""
    scene, model, start = hand
    peer = AdmmContactPeer(scene)
    forces = PeerForces(scene, peer)
    for q, v in [(start.q, start.v), off_the_grasp(scene, start, 1e-2)]:
        terms = peer.terms(q, v)
        np.testing.assert_allclose(forces(q, v, terms.jacobian), applied(model, q, v, 0.0), rtol=0, atol=1e-10)


def test_peer_rk4_loop_follows_pinstabs_run(hand):
    """The peer's RK4 loop (an ADMM solve per stage at 1e-12, Baumgarte 100 / 20, 1 ms, RK4 on the
    configuration group) and pinstab's ``simulate`` with the same scheme, step and gains, 0.1 s: the
    same states to 1e-10 and forces to 1e-9 N, the fingertips on their points on the ball to 1e-11 m."""
    scene, model, start = hand
    trajectory = simulate(scene, "baumgarte", "rk4", 1e-3, 0.1, kp=100.0, kd=20.0)
    run = run_peer(scene, start.q, start.v, PeerSettings("rk4", 1e-3, tolerance=TOLERANCE), 0.1)
    assert run.failed == 0 and len(run.t) == len(trajectory.t)
    np.testing.assert_allclose(run.q, trajectory.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(run.forces, trajectory.multipliers, rtol=0, atol=AGREEMENT)
    assert np.abs(run.q - start.q).max() > 1e-4  # the push moved the grasp
    model.kin.update_positions(run.q[-1])
    assert max(contact.slip(model.kin) for contact in scene.constraints) < 1e-11


# -- the peer on the box of test_contacts: closed forms --------------------------------------------------
def box_solution(push: float, height: float):
    scene = box_scene(push=(push, 0.0, 0.0), height=height)
    model = ConstrainedModel(scene)
    peer = AdmmContactPeer(scene, TOLERANCE)
    solution = peer.solve(scene.q0, scene.v0, applied(model, scene.q0, scene.v0, 0.0))
    assert_converged(solution)
    return peer.world_forces(solution), solution.motion


@pytest.mark.parametrize("height", [0.0, 0.02])
def test_peer_sticking_box_closed_form(height):
    """A 1 N push < mu m g: the normal forces carry m g, the friction forces the push, the front corners
    carry F (0.025 + h) / 0.1 more than the back ones (moments about the centre), the box stays put."""
    forces, acceleration = box_solution(1.0, height)
    np.testing.assert_allclose(forces.sum(axis=0), [-1.0, 0.0, MASS * GRAVITY], rtol=0, atol=1e-9)
    assert forces[:2, 2].sum() - forces[2:, 2].sum() == pytest.approx(1.0 * (0.025 + height) / 0.1, abs=1e-9)
    assert np.all(np.hypot(forces[:, 0], forces[:, 1]) < MU * forces[:, 2])
    np.testing.assert_allclose(acceleration, 0.0, atol=1e-9)


@pytest.mark.parametrize("height", [0.0, 0.02])
def test_peer_sliding_box_closed_form(height):
    """A 6 N push > mu m g (pinstab's sticking rows refuse it, test_contacts): ADMM's cones let the box
    slide: every contact on its cone's edge, friction mu m g against the push, a_x = (F - mu m g) / m,
    no rotation, front minus back normal force (F h + mu m g 0.025) / 0.1."""
    forces, acceleration = box_solution(6.0, height)
    friction = MU * MASS * GRAVITY
    np.testing.assert_allclose(forces.sum(axis=0), [-friction, 0.0, MASS * GRAVITY], rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.hypot(forces[:, 0], forces[:, 1]), MU * forces[:, 2], rtol=0, atol=1e-9)
    np.testing.assert_allclose(acceleration, [(6.0 - friction) / MASS, 0, 0, 0, 0, 0], rtol=0, atol=1e-9)
    front_minus_back = forces[:2, 2].sum() - forces[2:, 2].sum()
    assert front_minus_back == pytest.approx((6.0 * height + friction * 0.025) / 0.1, abs=1e-9)


def test_peer_velocity_level_loop_keeps_the_box_in_place():
    """The velocity-level loop (impulses, 1 ms, 0.1 s) on the sticking box: the box does not move
    (1e-10 m) and the impulses over a step carry m g and the push to 1e-6 N (forces = impulses / dt: the
    position correction (erp / dt) e on the box's 1e-12 m of drift makes 1e-7 N)."""
    scene = box_scene()
    run = run_peer(scene, scene.q0, scene.v0, PeerSettings("velocity-level", 1e-3, tolerance=TOLERANCE), 0.1)
    assert run.failed == 0
    assert np.abs(run.q - scene.q0).max() < 1e-10
    for forces in run.forces:  # pinstab's convention: (n, t1, t2) per contact; to world axes
        world = sum(c.selection.T @ forces[3 * i : 3 * i + 3] for i, c in enumerate(scene.constraints))
        np.testing.assert_allclose(world, [-1.0, 0.0, MASS * GRAVITY], rtol=0, atol=1e-6)


def test_peer_refuses_contacts_without_a_cone():
    with pytest.raises(PinstabError, match=r"plane contact 'c0' is frictionless; give it a mu"):
        AdmmContactPeer(box_scene(mu=None))
