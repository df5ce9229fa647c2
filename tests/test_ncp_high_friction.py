"""Time-stepping contacts over the whole friction range mu in [0, MAX_FRICTION] (issue 34): the checked cone solve
(pinstab/solvers/ncp.py) against closed forms, the scenes against their closed forms and their floors, and a solve
that no solver meets ending the run by name.

Measured (these tests, dt = 1 ms): Pinocchio's ADMM alone misses the painleve-rod's first step at mu = 4 by
0.9 m/s; the checked solve meets the closed-form sticking impulse to 2e-12 N s at mu = 4 to 10 (ADMM on cones of
1, 156 to 194 iterations) and at mu = 1000 (PGS after ADMM's miss, 20 iterations). The rod's end goes at most
4.8e-5 m (mu = 0) to 1.9e-7 m (mu = 10) into the floor, 0.87 (mu = 0) of the bound dt^2 omega^2 l / 2 and a
quarter of it at dt / 2; the incline's and box-push's accelerations match g (sin - mu cos) and F / m - mu g to
2e-14 relative, their resting cubes move less than 1e-12 m in 1 s.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pinocchio as pin
import pytest
from fuzzing import cli, contact_gaps, plane_contacts
from test_contact_stepping import rod_delassus

from pinstab.bench.python_stepper import PythonStepper
from pinstab.contact.coefficients import MAX_FRICTION
from pinstab.errors import ContactInfeasibleError, ContactSolveError
from pinstab.generators import ROD_SPEED
from pinstab.integration.contact_stepping import ContactStepper
from pinstab.runinfo import SolverStatistics
from pinstab.scene import Scene, bundled_scenes, load_scene, read_scene_file, scene_from_dict
from pinstab.simulate import simulate
from pinstab.simulate.contacts import stepping_parts
from pinstab.simulate.loop import start_state
from pinstab.solvers import ncp
from pinstab.solvers.ncp import CONE_ORDER, NcpSolver, friction_cones, ncp_residual

G, DT = 9.81, 1e-3
CHECKED = {"ADMM converged", "PGS converged"}  # the statuses of a solve that met the contact law
ROD_HALF = 0.5  # [m]


def rod_problem() -> tuple[np.ndarray, np.ndarray]:
    """The painleve-rod's first step in Pinocchio's rows (t1, t2, n) = (y, -x, z): D [1/kg] and g [m/s]. Out of
    the rod's plane an impulse at the end turns the rod about the axis normal to it and to y: 1/m + l^2 / I = 4."""
    in_plane = rod_delassus()  # (x, z)
    flip = np.diag([-1.0, 1.0])  # t2 = -x
    delassus = np.zeros((3, 3))
    delassus[0, 0] = 1.0 + ROD_HALF**2 / (1.0 / 12)
    delassus[1:, 1:] = flip @ in_plane @ flip
    return delassus, np.array([0.0, ROD_SPEED, -G * DT])


def sticking_impulse() -> np.ndarray:
    """The plastic sticking impulse of the rod's first step (t1, t2, n) [N s]: D P + g = 0."""
    delassus, g = rod_problem()
    return -np.linalg.solve(delassus, g)


def solve_rod(solver: NcpSolver, mu: float) -> np.ndarray:
    """The rod's first step through :meth:`NcpSolver.solve_contacts` (pinstab's rows (n, t1, t2), J = 1), back in
    Pinocchio's rows."""
    delassus, g = rod_problem()
    impulse = solver.solve_contacts(np.eye(3), CONE_ORDER.T @ delassus @ CONE_ORDER, CONE_ORDER.T @ g, [0], [mu])
    return CONE_ORDER @ impulse[0]


def checked(run) -> None:
    """Every cone solve of ``run`` met the contact law."""
    statuses = set(run.info.solver_statistics.status_counts)
    assert statuses and statuses <= CHECKED, statuses


def with_friction(name: str, mu: float, push: float | None = None) -> Scene:
    """Bundled scene ``name`` with every contact's mu set (its generator's parameter, else each contact's entry),
    and box-push's push [N] along x."""
    if name in ("incline", "painleve-rod", "sphere-spin", "pinch"):
        return load_scene(name, mu=mu)
    path = bundled_scenes()[name]
    data = read_scene_file(path)
    for contact in data["contacts"]:
        contact["mu"] = mu
    if push is not None:
        data["forces"][0]["force"] = [push, 0.0, 0.0]
    return scene_from_dict(data, name=name, base_dir=path.parent, source=path)


# -- the checked solve ---------------------------------------------------------------------------------------
def test_admm_alone_misses_the_rods_first_step_at_mu_4():
    """Why the cones are scaled: Pinocchio's ADMM on the cone of 4 itself ends 0.9 m/s off the law."""
    delassus, g = rod_problem()
    solver = NcpSolver(3)
    impulse = solver.solve(delassus, g, *friction_cones([4.0]))
    assert not solver.status().converged
    assert ncp_residual(delassus, g, impulse, [4.0]) > 0.1  # [m/s] of a 1 m/s slip


@pytest.mark.parametrize("mu", [4.0, 5.0, 7.0, MAX_FRICTION])
def test_the_checked_solve_meets_the_sticking_impulse(mu):
    impulse, solver = sticking_impulse(), NcpSolver(3)
    assert impulse[2] > 0 and math.hypot(*impulse[:2]) < 1.31 * impulse[2]  # inside every cone of mu >= 1.31
    np.testing.assert_allclose(solve_rod(solver, mu), impulse, rtol=0, atol=1e-9)
    assert solver.method == "ADMM" and solver.status().converged
    assert solver.residual <= solver.tolerance == pytest.approx(1e-6 * ROD_SPEED)


def test_pgs_takes_over_where_admm_misses():
    """At mu = 1000 (beyond the scenes' range: the solver takes any cone) ADMM misses even the cones of 1; PGS
    meets the law, counted as a fallback."""
    solver, statistics = NcpSolver(3), SolverStatistics()
    np.testing.assert_allclose(solve_rod(solver, 1000.0), sticking_impulse(), rtol=0, atol=1e-9)
    solver.record(statistics)
    assert solver.method == "PGS" and statistics.status_counts == {"PGS converged": 1} and statistics.fallbacks == 1


def test_the_numpy_step_falls_back_to_pgs_as_the_compiled_one():
    """The NumPy reference of the compiled step (pinstab/bench/python_stepper.py) hands ADMM's miss at mu = 1000 to PGS
    as the compiled solve does: the sticking impulse to 1e-9 N s, the compiled solve's answer to 1e-12 N s."""
    scene = load_scene("painleve-rod")
    _, reference, _, _ = stepping_parts(scene, DT, *start_state(scene, None, None), PythonStepper)
    delassus, g = rod_problem()
    impulse = reference._cone_solve(delassus, g, [1000.0])
    np.testing.assert_allclose(impulse, sticking_impulse(), rtol=0, atol=1e-9)
    solver = NcpSolver(3)
    compiled = solver.cones.solve(delassus, g, np.array([1000.0]), ncp.CHECK_RTOL)
    solver.read_status()
    assert solver.method == "PGS"
    np.testing.assert_allclose(impulse, compiled, rtol=0, atol=1e-12)


def test_a_solve_no_solver_meets_says_so():
    solver, statistics = NcpSolver(3, max_iterations=3), SolverStatistics()
    impulse = solve_rod(solver, 4.0)
    solver.record(statistics)
    assert not solver.status().converged and statistics.status_counts == {"ADMM, PGS not converged": 1}
    delassus, g = rod_problem()
    assert solver.residual == ncp_residual(delassus, g, impulse, [4.0]) > solver.tolerance


@pytest.mark.parametrize("mu", [0.0, 4.0, MAX_FRICTION])
def test_residual_of_no_impulse_is_the_projection_by_hand(mu):
    """lambda = 0: sigma = g, the De Saxce velocity (0, v, mu v - g dt); -rho of it projects on the cone's
    boundary at (mu v - mu v + g dt) / (1 + mu^2) along its axis: |P| / rho = g dt / sqrt(1 + mu^2)."""
    delassus, g = rod_problem()
    expected = G * DT / math.sqrt(1 + mu * mu)
    assert ncp_residual(delassus, g, np.zeros(3), [mu]) == pytest.approx(expected, rel=1e-12)
    assert ncp_residual(delassus, g, sticking_impulse(), [max(mu, 2.0)]) <= 1e-15
    assert ncp_residual(delassus, g, np.full(3, np.nan), [mu]) == math.inf


# -- the painleve-rod: never through the floor ----------------------------------------------------------------
def rod_run(mu: float, dt: float = DT):
    """The rod's run (1 s), its end's gaps [m] and the bound dt^2 omega^2 l / 2 [m] on a step's chord error."""
    scene = load_scene("painleve-rod", mu=mu)
    run = simulate(scene, dt=dt, duration=1.0, contacts="stepping")
    omega = np.linalg.norm(run.v[:, 3:6], axis=1).max()
    return run, contact_gaps(scene, run.q)[:, 0], dt**2 * omega**2 * ROD_HALF / 2


@pytest.mark.parametrize("mu", [0.0, 0.5, 1.0, 2.0, 4.0, 5.0, 7.0, MAX_FRICTION])
def test_the_rods_end_stays_on_the_floor(mu):
    """Every step's solve met the law, the state stays finite and the end never goes further into the floor than
    the chord of one step misses the arc of the rod's turn, dt^2 omega^2 l / 2 (the next step takes it back)."""
    run, gaps, bound = rod_run(mu)
    checked(run)
    assert np.isfinite(run.q).all() and np.isfinite(run.v).all()
    assert gaps.min() >= -bound


def test_the_rods_penetration_is_the_schemes_second_order_chord():
    depths = [-rod_run(0.0, dt)[1].min() for dt in (DT, DT / 2)]
    assert 3.6 <= depths[0] / depths[1] <= 4.4  # measured 4.0


@pytest.mark.parametrize("mu", [4.0, 5.0, MAX_FRICTION])
def test_the_rods_end_stops_dead_beyond_the_bound(mu):
    """Where ADMM used to miss (mu = 4, 5) or end in NaN (10): the first step is the sticking impulse."""
    run = simulate(load_scene("painleve-rod", mu=mu), dt=DT, duration=0.01, contacts="stepping")
    first = run.info.contact_events[0]
    assert (first["to"], first["cause"]) == ("sticking", "start")
    normal, across, along = first["impulse"]
    np.testing.assert_allclose([across, along, normal], sticking_impulse(), rtol=0, atol=1e-9)


def test_the_cli_runs_the_rod_at_mu_4_without_a_miss():
    outcome = cli(["run", "painleve-rod", "--param", "mu=4", "--contacts", "stepping", "--json", "--quiet"])
    assert outcome.code == 0
    assert set(json.loads(outcome.out)["solver_status"]) <= CHECKED


# -- closed forms --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("theta", "mu"), [(0.5, 0.0), (0.5, 0.3), (0.5, 0.54), (0.5, 0.55), (0.5, 1.0), (0.5, 10.0),
                                           (0.78, 1.0), (0.78, MAX_FRICTION)])  # fmt: skip
def test_incline_rests_above_the_friction_angle_and_slides_below(theta, mu):
    """From rest the cube sticks for mu >= tan(theta), else slides at a = g (sin - mu cos) (v = a t exactly for
    semi-implicit Euler on a constant acceleration). Slopes up to 0.78 rad (tan 0.99): beyond 45 deg the cube of
    equal half-width and half-height tips over its lower edge instead."""
    run = simulate(load_scene("incline", theta=theta, mu=mu), dt=DT, duration=1.0, contacts="stepping")
    checked(run)
    acceleration = G * (math.sin(theta) - mu * math.cos(theta))
    if mu >= math.tan(theta):
        assert np.abs(run.q[:, :3] - run.q[0, :3]).max() <= 1e-10  # measured 1.1e-13 m
    else:
        assert run.v[-1, 0] == pytest.approx(acceleration * 1.0, rel=1e-9)
        assert np.abs(run.q[:, 2] - 0.05).max() <= 1e-12 and np.abs(run.q[:, 3:6]).max() <= 1e-12


@pytest.mark.parametrize(("mu", "push"), [(0.0, 6.0), (0.3, 6.0), (0.6, 6.0), (0.62, 6.0), (1.0, 6.0), (10.0, 6.0),
                                          (2.5, 30.0), (3.5, 40.0), (MAX_FRICTION, 30.0)])  # fmt: skip
def test_box_push_slides_at_the_closed_form_or_holds(mu, push):
    """The 1 kg box (0.2 x 0.1 x 0.05 m) pushed at its centre with F along x: it holds for F <= mu m g, else
    slides at F / m - mu g. It neither tips sliding (mu h = 3.5 x 0.025 m < half-length 0.1 m) nor holding
    (F h = 30 N x 0.025 m < m g x 0.1 m)."""
    scene = with_friction("box-push", mu, push)
    mass = pin.computeTotalMass(scene.model)
    run = simulate(scene, dt=DT, duration=1.0, contacts="stepping")
    checked(run)
    assert contact_gaps(scene, run.q).min() >= -1e-12
    if push <= mu * mass * G:
        assert np.abs(run.q[:, :3] - run.q[0, :3]).max() <= 1e-10  # measured 2.6e-13 m
        assert {event["to"] for event in run.info.contact_events} == {"sticking"}
    else:
        assert run.v[-1, 0] == pytest.approx(push / mass - mu * G, rel=1e-9)
        assert np.abs(run.q[:, 3:6]).max() <= 1e-12


# -- the other contact scenes at the ends of the range -------------------------------------------------------
def chord_bound(scene: Scene, run) -> float:
    """How far [m] a step may leave a plane contact's point inside its plane: the point p moves on the screw of
    its body's twist, off the chord dt v_p by dt^2 |omega x v_p| / 2 <= dt^2 Omega (V + Omega R) / 2 (Omega, V the
    largest angular and linear speeds of the scene's first joint, a free flyer; R the contact frames' largest
    distance from their joints plus radius), and 1e-12 m of rounding."""
    reach = max(
        np.linalg.norm(scene.model.frames[c.frame_a].placement.translation) + c.radius for c in plane_contacts(scene)
    )
    omega = np.linalg.norm(run.v[:, 3:6], axis=1).max()
    speed = np.linalg.norm(run.v[:, :3], axis=1).max()
    return DT**2 * omega * (speed + omega * reach) / 2 + 1e-12


@pytest.mark.parametrize("mu", [0.0, MAX_FRICTION])
@pytest.mark.parametrize("name", ["sphere-spin", "pinch", "allegro-sphere", "allegro-tilt", "trifinger-cube"])
def test_contact_scenes_at_the_ends_of_the_range(name, mu):
    """Every solve met the law and the state stays finite; a plane contact's point stays within
    :func:`chord_bound` of its plane (grasp contacts, on the tangent plane of a curved object, are not measured)."""
    scene = with_friction(name, mu)
    run = simulate(scene, dt=DT, duration=0.1, contacts="stepping")
    checked(run)
    assert np.isfinite(run.q).all() and np.isfinite(run.v).all()
    if plane_contacts(scene):
        assert contact_gaps(scene, run.q).min() >= -chord_bound(scene, run)


def test_allegro_lift_without_friction_cannot_hold_the_ball():
    """mu = 0: the grasp controller finds no force inside the cones that lifts the ball, by name (and holds it at
    the other end)."""
    with pytest.raises(ContactInfeasibleError, match="no contact forces move the object"):
        simulate(with_friction("allegro-lift", 0.0), dt=DT, duration=0.1, contacts="stepping")
    checked(simulate(with_friction("allegro-lift", MAX_FRICTION), dt=DT, duration=0.1, contacts="stepping"))


# -- a solve no solver meets ----------------------------------------------------------------------------------
@pytest.fixture
def miss_from(monkeypatch):
    """Make every cone solve of a step from t >= ``start`` [s] miss (no answer is within a negative tolerance)."""

    def set_up(start: float) -> None:
        step, tolerance = ContactStepper.step, ncp.CHECK_RTOL

        def missing(self, q, v, t, dt):
            ncp.CHECK_RTOL = -1.0 if t >= start else tolerance
            return step(self, q, v, t, dt)

        monkeypatch.setattr(ncp, "CHECK_RTOL", tolerance)  # restored after the test
        monkeypatch.setattr(ContactStepper, "step", missing)

    return set_up


def test_a_step_no_solver_meets_ends_the_run_kept_up_to_it(miss_from):
    """sphere-spin rolls from t* = 0.242 s; a miss from t = 0.25 s (in the loop's check interval that holds the
    switch, which its replay to locate the failure steps again) ends the run there, its samples those of the
    run without the miss and its events once each."""
    whole = simulate("sphere-spin", dt=DT, duration=1.0, contacts="stepping")
    miss_from(0.25)
    with pytest.raises(ContactSolveError, match=r"at t = 0.25 s the impulses of contacts ground were not found: ") as c:
        simulate("sphere-spin", dt=DT, duration=1.0, contacts="stepping")
    kept = c.value.trajectory
    assert c.value.contacts == ["ground"] and c.value.time == pytest.approx(0.25)
    assert kept.t[-1] == pytest.approx(0.25) and np.array_equal(kept.q, whole.q[: len(kept.t)])
    assert kept.info.contact_events == whole.info.contact_events
    assert kept.info.stopped["error"] == "ContactSolveError"


def test_the_cli_exits_5_on_a_step_no_solver_meets(miss_from):
    miss_from(0.0)
    outcome = cli(["run", "incline", "--contacts", "stepping", "--quiet"])
    assert outcome.code == 5
    assert "impulses of contacts corner0, corner1, corner2, corner3 were not found" in outcome.message
    assert "neither ADMM nor PGS" in outcome.message and "Traceback" not in outcome.err
