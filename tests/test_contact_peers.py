"""The contacts benchmark's closed forms and metrics (``pinstab.bench.contact_scenes``) against hand
numbers and synthetic trajectories, and its peers -- the Moreau--Jean loop over Pinocchio's ADMM
(``admm_contacts``) and MuJoCo (``mujoco_contacts``) -- against the closed forms on short runs, to the
loose tolerances their first-order steps allow (stated per test, with the figure measured)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from pinstab import PinstabError, load_scene
from pinstab.bench import contact_scenes as cs
from pinstab.bench import mujoco_contacts as mj
from pinstab.bench.admm_contacts import SteppingSettings, pinch_problem, run_contacts, scene_problem

G = 9.81
STICK, SLIDE = (math.radians(20), 0.37), (math.radians(30), 0.3)
SPIN = {"v0": 2.0, "omega0": 5.0, "mu": 0.3, "radius": 0.1}


# -- closed forms, by hand ----------------------------------------------------------------------------------
def test_closed_forms_against_hand_numbers():
    # 9.81 (sin 30 - 0.3 cos 30) 2^2 / 2 = 9.81 x 0.2401924 x 2
    assert cs.slide_distance(*SLIDE, 2.0) == pytest.approx(4.712575, abs=1e-6)
    assert cs.slide_distance(*STICK, 2.0) == 0.0  # 0.37 > tan 20 = 0.364: it sticks
    t_star, v_star = cs.rolling_onset(**SPIN)
    assert t_star == pytest.approx(5.0 / 20.601, abs=1e-12)  # 2 (2 + 0.5) / (7 x 0.3 x 9.81)
    assert v_star == pytest.approx(9.0 / 7.0, abs=1e-15)  # (10 - 1) / 7
    apexes, rest = cs.bounce(1.0, 0.5)
    np.testing.assert_allclose(apexes, [0.25, 0.0625, 0.015625, 0.00390625, 0.0009765625], rtol=1e-15)
    assert rest == pytest.approx(3 * 0.4515236, abs=1e-6)  # t0 = sqrt(2 / 9.81) = 0.4515236
    assert cs.pinch_drop(0.2, 5.0, 0.5, 1.0) == pytest.approx((9.81 - 4.0) / 2, abs=1e-15)
    assert cs.pinch_drop(0.5, 10.0, 0.5, 1.0) == 0.0  # 2 mu F = 10 N >= m g = 4.905 N


def test_restitution_damping_bounces_a_spring_damper_by_e():
    """The damping ratio zeta makes a linear spring-damper's half oscillation keep exp(-zeta pi / sqrt(1 -
    zeta^2)) of the speed; checked here on the ODE x'' + 2 zeta w x' + w^2 x = 0 itself (w = 1)."""
    from scipy.integrate import solve_ivp

    for e in (0.2, 0.5, 0.9):
        zeta = mj.restitution_damping(e)
        leave = solve_ivp(
            lambda t, y, zeta=zeta: [y[1], -2 * zeta * y[1] - y[0]],
            (0, 10),
            [0.0, -1.0],
            events=lambda t, y: y[0] if t > 1e-6 else -1.0,
            rtol=1e-12,
            atol=1e-12,
        )
        assert leave.y_events[0][0][1] == pytest.approx(e, rel=1e-8)  # back at x = 0 with speed e
    assert mj.restitution_damping(0.0) == 1.0


# -- metrics on synthetic samples ------------------------------------------------------------------------
def samples(t, position, velocity, angular=None) -> cs.ObjectSamples:
    return cs.ObjectSamples(t, position, velocity, np.zeros_like(position) if angular is None else angular)


def test_creep_is_the_largest_displacement_along_the_axes():
    t = np.arange(4.0)
    position = np.array([[0, 0, 1], [3e-6, 4e-6, 0], [1e-6, 0, 5], [0, 0, 0.0]])
    moving = samples(t, position, np.zeros_like(position))
    assert cs.creep(moving, (0, 1)) == pytest.approx(5e-6, rel=1e-12)
    assert cs.creep(moving, (2,)) == pytest.approx(4.0, rel=1e-12)


def test_slip_end_and_apexes_and_rest_on_exact_trajectories():
    # sphere-spin, exact: slip 2.5 - 3.5 mu g t until t*, then 0; samples every 1 ms
    t_star, v_star = cs.rolling_onset(**SPIN)
    t = np.arange(0, 0.5, 1e-3)
    slip = np.maximum(2.5 - 3.5 * SPIN["mu"] * G * t, 0.0)
    v = np.where(t < t_star, 2.0 - SPIN["mu"] * G * t, v_star)
    angular = np.zeros((len(t), 3))
    angular[:, 1] = (v - slip) / SPIN["radius"]
    ball = samples(t, np.zeros((len(t), 3)), np.column_stack([v, 0 * t, 0 * t]), angular)
    assert cs.slip_end(ball, SPIN["radius"]) == pytest.approx(0.243, abs=1e-12)  # the first sample past t* = 0.2427
    # the bouncing ball, exact (released at 0, impacts at t0, t0 + 2 t0 e, t0 + 2 t0 (e + e^2), ...), every 0.5 ms
    apexes, rest = cs.bounce(1.0, 0.5)
    t0 = math.sqrt(2 / G)
    impacts = np.concatenate([[0.0, t0], t0 + 2 * t0 * np.cumsum(0.5 ** np.arange(1, 40))])
    speeds = np.concatenate([[0.0], math.sqrt(2 * G) * 0.5 ** np.arange(1, 41)])
    t = np.arange(0, 1.6, 5e-4)
    k = np.searchsorted(impacts, t, side="right") - 1
    since = t - impacts[k]
    gap = np.where(k == 0, 1.0 - G * t**2 / 2, speeds[k] * since - G * since**2 / 2)
    vz = np.where(k == 0, -G * t, speeds[k] - G * since)
    at_rest = t >= rest
    gap[at_rest], vz[at_rest] = 0.0, 0.0
    path = samples(t, np.column_stack([0 * t, 0 * t, gap + cs.BALL_RADIUS]), np.column_stack([0 * t, 0 * t, vz]))
    np.testing.assert_allclose(cs.apex_gaps(path, cs.BALL_RADIUS)[:5], apexes, rtol=1e-12)
    # within a sample (5e-4 s) and the bounces below REST_SPEED: 2 REST_SPEED e / (g (1 - e)) = 2e-4 s
    assert cs.rest_time(path) == pytest.approx(rest, abs=7e-4)


def test_free_flyer_samples_are_in_world_axes():
    model = pin.Model()
    joint = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "body")
    model.appendBodyToJoint(joint, pin.Inertia.FromSphere(1.0, 0.1), pin.SE3.Identity())
    q = pin.neutral(model)
    q[3:7] = [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)]  # a quarter turn about z
    v = np.array([1.0, 0, 0, 2.0, 0, 0])  # along and about the body's x
    got = cs.free_flyer_samples(model, np.zeros(1), q[None], v[None])
    np.testing.assert_allclose(got.velocity[0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(got.angular[0], [0, 2, 0], atol=1e-15)


# -- the ADMM loop against the closed forms (dt = 1 ms) ---------------------------------------------------
def admm(problem, duration, every=10):
    run = run_contacts(problem, SteppingSettings(1e-3), duration, every)
    assert run.failed == 0
    return cs.free_flyer_samples(problem.model, run.t, run.q, run.v)


def test_admm_loop_incline_slides_and_sticks():
    slide = admm(scene_problem(load_scene("incline", theta=SLIDE[0], mu=SLIDE[1])), 2.0)
    # semi-implicit Euler under a constant force: x(T) (1 + dt / T), 5.0e-4 at 2 s
    assert cs.relative_error(slide.position[-1, 0], cs.slide_distance(*SLIDE, 2.0)) <= 1e-3
    stick = admm(scene_problem(load_scene("incline", theta=STICK[0], mu=STICK[1])), 1.0)
    assert cs.creep(stick, (0, 1)) <= 1e-9  # 7.4e-12 m over 2 s


def test_admm_loop_sphere_spin_rolls_within_a_step():
    spin = admm(scene_problem(load_scene("sphere-spin", **SPIN)), 0.4, every=1)
    t_star, v_star = cs.rolling_onset(**SPIN)
    assert 0 <= cs.slip_end(spin, SPIN["radius"]) - t_star <= 1e-3  # the step in which it sticks
    assert cs.relative_error(spin.velocity[-1, 0], v_star) <= 1e-9  # 3.4e-13: Euler is exact for constant forces


def test_admm_loop_bouncing_ball_apexes_and_rest():
    ball = admm(scene_problem(load_scene("bouncing-ball", height=1.0, restitution=0.5)), 1.6, every=1)
    apexes, rest = cs.bounce(1.0, 0.5)
    np.testing.assert_allclose(cs.apex_gaps(ball, cs.BALL_RADIUS)[:3], apexes[:3], rtol=2e-2)  # 8.3e-3
    assert cs.relative_error(cs.rest_time(ball), rest) <= 2e-2  # 7.0e-3


def test_admm_loop_pinch_holds_and_slips():
    hold = admm(pinch_problem(0.5, 10.0, 0.5), 1.0)
    assert cs.creep(hold, (2,)) <= 1e-9  # 1.1e-11 m
    slip = admm(pinch_problem(0.2, 5.0, 0.5), 1.0)
    assert cs.relative_error(-slip.position[-1, 2], cs.pinch_drop(0.2, 5.0, 0.5, 1.0)) <= 1.5e-3  # 1.0e-3 = dt / T


def test_admm_loop_refuses_scenes_with_other_constraints():
    with pytest.raises(PinstabError, match="plane contacts only"):
        scene_problem(load_scene("fourbar"))


# -- MuJoCo at dt = 1 ms, elliptic cones, impratio 100, noslip ---------------------------------------------
BEST = mj.MujocoSettings(1e-3, impratio=100.0, noslip_iterations=20)


def test_mujoco_incline_and_pinch():
    stick, _ = mj.run_mujoco(mj.incline(*STICK), BEST, 2.0, 10)
    assert cs.creep(stick, (0, 1)) <= 2e-5  # 6.8e-6 m: soft contacts creep
    slide, _ = mj.run_mujoco(mj.incline(*SLIDE), BEST, 2.0, 10)
    assert cs.relative_error(slide.position[-1, 0], cs.slide_distance(*SLIDE, 2.0)) <= 2e-2  # 7.6e-3
    slip, _ = mj.run_mujoco(mj.pinch(0.2, 5.0, 0.5), BEST, 1.0, 10)
    assert cs.relative_error(-slip.position[-1, 2], cs.pinch_drop(0.2, 5.0, 0.5, 1.0)) <= 2e-3  # 4.4e-4


def test_mujoco_sphere_spin_and_ball():
    spin, _ = mj.run_mujoco(mj.sphere_spin(**SPIN), BEST, 0.5, 1)
    t_star, v_star = cs.rolling_onset(**SPIN)
    assert abs(cs.slip_end(spin, SPIN["radius"]) - t_star) <= 5e-3  # 2.3e-3 s
    assert cs.relative_error(spin.velocity[-1, 0], v_star) <= 1e-3  # 4.6e-4
    ball, _ = mj.run_mujoco(mj.bouncing_ball(1.0, 0.5), mj.MujocoSettings(1e-4), 1.6, 1)
    apexes, _ = cs.bounce(1.0, 0.5)
    # restitution through solref's damping ratio: the first apex -3.9e-3 (the later ones 20 % and more high)
    assert cs.apex_gaps(ball, cs.BALL_RADIUS)[0] == pytest.approx(apexes[0], rel=2e-2)
