"""KKT backends against Pinocchio's own algorithm and against a non-redundant formulation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pinstab import SolverError, build_system, load_scene, simulate
from pinstab.paths.native import NativeDynamics
from pinstab.scene import scene_from_dict
from pinstab.solvers import PinocchioSolver
from pinstab.solvers.base import KKTProblem
from pinstab.solvers.proxsuite_ import direct_solve


def native_accelerations(scene, kp, kd, states):
    """Pinocchio's constraintDynamics, built here from the scene's closure frames (3-D contacts)."""
    model = scene.model
    models, datas = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
    for closure in scene.constraints:
        fa, fb = model.frames[closure.frame_a], model.frames[closure.frame_b]
        rcm = pin.RigidConstraintModel(
            pin.ContactType.CONTACT_3D,
            model,
            fa.parentJoint,
            fa.placement,
            fb.parentJoint,
            fb.placement,
            pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
        )
        rcm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(kp, kd))
        models.append(rcm)
        datas.append(rcm.createData())
    data = model.createData()
    pin.initConstraintDynamics(model, data, models, datas)
    settings = pin.ProximalSettings(1e-14, 1e-14, 1e-12, 100)
    return [
        pin.constraintDynamics(model, data, q, v, np.zeros(model.nv), models, datas, settings).copy() for q, v in states
    ]


@pytest.mark.parametrize("scene_name", ["fourbar", "slider-crank"])
@pytest.mark.parametrize("solver", ["dense", "proxsuite"])
def test_baumgarte_reproduces_pinocchio_corrector(scene_name, solver):
    kp, kd = 10.0, 2 * np.sqrt(10.0)
    scene = load_scene(scene_name)
    # no torque element in the native call: drop them for both
    scene.forces.clear()
    # start off the manifold so that the corrector terms are active along the whole run
    traj = simulate(
        scene,
        method="baumgarte",
        kp=kp,
        kd=kd,
        integrator="semi-implicit-euler",
        dt=1e-3,
        duration=0.5,
        solver=solver,
        assemble_initial=False,
    )
    assert traj.position_drift[0] > 1e-3
    system = build_system(scene, "baumgarte", solver, kp=kp, kd=kd)
    states = list(zip(traj.q[::25], traj.v[::25], strict=True))
    native = native_accelerations(scene, kp, kd, states)
    for (q, v), expected in zip(states, native, strict=True):
        np.testing.assert_allclose(
            system.dynamics(q, v, 0.0).acceleration, expected, rtol=0, atol=1e-10 * max(1.0, np.abs(expected).max())
        )


def test_pinocchio_method_tracks_baumgarte_run():
    """The same corrector inside Pinocchio gives the same trajectory as pinstab's baumgarte."""
    a = simulate("fourbar", method="baumgarte", solver="dense", dt=1e-3, duration=1.0)
    b = simulate("fourbar", method="pinocchio", dt=1e-3, duration=1.0)
    np.testing.assert_allclose(a.q, b.q, atol=1e-9)
    np.testing.assert_allclose(a.multipliers, b.multipliers, atol=1e-6)


def test_fivebar_redundant_rows_give_the_reduced_accelerations():
    """proxsuite on the 3-row point closure == dense on the 2-row planar-point closure."""
    redundant = load_scene("fivebar")
    reduced = load_scene("fivebar")
    reduced.constraints.clear()
    planar = scene_from_dict(
        {
            "robot": {"urdf": str(redundant.urdf_path)},
            "closures": [
                {
                    "name": "end-effector",
                    "kind": "planar-point",
                    "plane": "xy",
                    "frame_a": "distal_left",
                    "offset_a": [0.4, 0.0, 0.0],
                    "frame_b": "distal_right",
                    "offset_b": [0.4, 0.0, 0.0],
                }
            ],
            "gravity": [0.0, -9.81, 0.0],
        }
    )
    traj = simulate(redundant, method="baumgarte", solver="proxsuite", dt=2e-3, duration=1.0)
    prox = build_system(redundant, "baumgarte", "proxsuite")
    dense = build_system(planar, "baumgarte", "dense")
    compared = 0
    for q, v in zip(traj.q[::20], traj.v[::20], strict=True):
        expected = dense.dynamics(q, v, 0.0).acceleration
        np.testing.assert_allclose(
            prox.dynamics(q, v, 0.0).acceleration, expected, atol=1e-9 * max(1.0, np.abs(expected).max())
        )
        compared += 1
    assert compared >= 5


def test_dense_refuses_redundant_rows_with_a_clear_error():
    with pytest.raises(SolverError, match=r"lost rank \(2 independent of 3 rows\).*end-effector.*proxsuite"):
        simulate("fivebar", method="baumgarte", solver="dense", dt=1e-3, duration=0.01)


def test_pinocchio_solver_refuses_planar_closure_on_a_spatial_mechanism():
    scene = scene_from_dict(
        {
            "robot": {"urdf": str(load_scene("delta").urdf_path)},
            "closures": [
                {
                    "name": "odd",
                    "kind": "planar-point",
                    "plane": "xy",
                    "frame_a": "forearm0",
                    "offset_b": [0.3, 0.0, -0.4],
                }
            ],
        }
    )
    with pytest.raises(SolverError, match="odd.*not on a planar mechanism"):
        simulate(scene, method="pinocchio", dt=1e-3, duration=0.01, assemble_initial=False)


def test_pinocchio_solver_hands_missed_constraints_to_proxqp():
    """Pinocchio with no corrector cannot apply a Baumgarte term it does not know: the residual check
    sees G a != rhs off the manifold and solves with ProxQP instead, which meets the rows."""
    scene = load_scene("fourbar")
    native = PinocchioSolver(NativeDynamics(scene.model, scene.constraints, kp=0.0, kd=0.0))
    system = build_system(scene, "baumgarte", "proxsuite", kp=100.0, kd=20.0)
    system.solver = native
    q, v = scene.q0, scene.v0  # not assembled: phi is about 0.1 m
    evaluation = system.dynamics(q, v, 0.0)
    assert native.statistics.fallbacks == 1
    reference = build_system(scene, "baumgarte", "dense", kp=100.0, kd=20.0).dynamics(q, v, 0.0)
    np.testing.assert_allclose(evaluation.acceleration, reference.acceleration, atol=1e-8)
    # on the manifold with matching gains, no fallback is needed
    traj = simulate(scene, method="pinocchio", dt=1e-3, duration=0.2)
    assert traj.info.solver_statistics.fallbacks == 0


@pytest.mark.parametrize("scene_name", ["fourbar", "slider-crank", "fivebar"])
def test_native_path_equals_the_general_one(scene_name):
    """The native path (Pinocchio's algorithm with its corrector) gives the accelerations and
    multipliers of the general path (pinstab kinematics + ProxQP, same gains) along a trajectory, off
    the manifold included; the slider-crank's motor and damper are applied on both."""
    scene = load_scene(scene_name)
    gains = dict(kp=10.0, kd=2 * np.sqrt(10.0))
    native = build_system(scene, "baumgarte", None, **gains)
    native.bind(1e-3, "rk4", scene.q0)
    assert native.path == "native" and native.path_reason == ""
    general = build_system(scene, "baumgarte", "proxsuite", solver_options={"eps_abs": 1e-12}, **gains)
    general.bind(1e-3, "rk4", scene.q0)
    assert general.path == "general" and "proxsuite" in general.path_reason
    traj = simulate(
        scene,
        method="baumgarte",
        integrator="semi-implicit-euler",
        dt=1e-3,
        duration=0.3,
        solver="proxsuite",
        assemble_initial=False,
    )
    for q, v in zip(traj.q[::30], traj.v[::30], strict=True):
        expected = general.dynamics(q, v, 0.1)
        got = native.acceleration(q, v, 0.1, 0)
        np.testing.assert_allclose(
            got, expected.acceleration, atol=1e-9 * max(1.0, np.abs(expected.acceleration).max())
        )
        np.testing.assert_allclose(
            native.multipliers(q, v, 0.1),
            expected.multipliers,
            atol=1e-7 * max(1.0, np.abs(expected.multipliers).max()),
        )
    assert native.statistics.fallbacks == 0


def test_native_path_hands_a_missed_check_to_the_general_path():
    """A native solve that misses its rows (here: the check expects another corrector than the one
    Pinocchio applies) is solved again the general way, counted as a fallback."""
    scene = load_scene("fourbar")
    system = build_system(scene, "baumgarte", None)
    system.bind(1e-3, "rk4", scene.q0)
    system.native.kp = 55.0
    expected = build_system(scene, "baumgarte", "dense").dynamics(scene.q0, scene.v0, 0.0).acceleration
    got = system.acceleration(scene.q0, scene.v0, 0.0, 0)  # off the manifold: the two disagree
    assert system.statistics.fallbacks == 1
    np.testing.assert_allclose(got, expected, atol=1e-8 * np.abs(expected).max())


@pytest.mark.parametrize(
    ("scene_name", "method", "solver", "integrator", "reason"),
    [
        ("delta", "baumgarte", None, "rk4", "weld"),  # the core path's (below)
        ("box-push", "baumgarte", None, "rk4", "cone rows"),
        ("fourbar", "baumgarte", "proxsuite", "rk4", "solver 'proxsuite' was named"),
        ("fourbar", "mukharlyamov", None, "rk4", "not Baumgarte"),  # held over the RK4 stages: the core path's
        ("fourbar", "mukharlyamov", None, "semi-implicit-euler", ""),
        ("fourbar", "projection", None, "rk4", ""),
        ("slider-crank", "baumgarte", None, "heun", ""),
    ],
)
def test_native_path_is_taken_where_it_applies(scene_name, method, solver, integrator, reason):
    scene = load_scene(scene_name)
    system = build_system(scene, method, solver)
    system.bind(1e-3, integrator, scene.q0)
    assert system.path == ("native" if not reason else "core" if reason in ("weld", "not Baumgarte") else "general")
    assert reason in (system.native_obstacle(scene.q0) or "")


def test_proxsuite_direct_solve_equals_proxqp_and_dense():
    """allegro-sphere (12 independent contact rows, nv = 22): the proxsuite backend's Cholesky solve (status
    'cholesky'), ProxQP itself (direct off) and the dense backend give the same accelerations (1e-10 relative)
    and multipliers (1e-8 relative) at states along a run; with direct off every status is ProxQP's."""
    scene = load_scene("allegro-sphere")
    trajectory = simulate(scene, duration=0.05, progress=False)
    systems = {
        "direct": build_system(scene, "baumgarte", "proxsuite"),
        "qp": build_system(scene, "baumgarte", "proxsuite", solver_options={"direct": False}),
        "dense": build_system(scene, "baumgarte", "dense"),
    }
    for q, v in zip(trajectory.q[::10], trajectory.v[::10], strict=True):
        results = {name: system.dynamics(q, v, 0.0) for name, system in systems.items()}
        expected = results["dense"]
        for name in ("direct", "qp"):
            scale_a, scale_f = np.abs(expected.acceleration).max(), np.abs(expected.multipliers).max()
            np.testing.assert_allclose(results[name].acceleration, expected.acceleration, atol=1e-10 * scale_a)
            np.testing.assert_allclose(results[name].multipliers, expected.multipliers, atol=1e-8 * scale_f)
    assert set(systems["direct"].solver.statistics.status_counts) == {"cholesky"}
    assert "cholesky" not in systems["qp"].solver.statistics.status_counts


def test_proxsuite_direct_solve_declines_redundant_rows():
    """fivebar's point closure on a planar mechanism (3 rows, rank 2): its out-of-plane row is zero, left out of the
    Cholesky solve (multiplier 0), which gives ProxQP's accelerations; with a row repeated (rows dependent) the
    Delassus pivot falls below DIRECT_PIVOT, the direct solve declines and ProxQP solves (the dense backend refuses
    it)."""
    scene = load_scene("fivebar")
    system = build_system(scene, "baumgarte", "proxsuite")
    proxqp = build_system(scene, "baumgarte", "proxsuite", solver_options={"direct": False})
    direct, by_qp = system.dynamics(scene.q0, scene.v0, 0.0), proxqp.dynamics(scene.q0, scene.v0, 0.0)
    assert set(system.solver.statistics.status_counts) == {"cholesky"} and direct.multipliers[2] == 0.0
    np.testing.assert_allclose(direct.acceleration, by_qp.acceleration, rtol=0, atol=1e-9)
    terms = system.model.dynamics_terms(scene.q0, scene.v0, 0.0)
    jacobian, rhs = terms.values.jacobian, -terms.values.drift
    assert np.abs(jacobian[2]).max() == 0.0 and np.abs(jacobian[:2]).max(axis=1).min() > 0.4
    repeated = [0, 1, 0]  # the third row the first one again: dependent rows
    problem = KKTProblem(
        scene.q0,
        scene.v0,
        0.0,
        terms.tau,
        terms.mass_matrix,
        terms.tau - terms.bias,
        jacobian[repeated],
        rhs[repeated],
        system.model.constraints.layout,
    )
    assert direct_solve(problem) is None


def test_proxsuite_direct_solve_of_a_scene_without_constraints():
    """The double pendulum alone (no constraint rows) with the proxsuite backend named: the free motion, equal to
    the native path's (Pinocchio's ABA) to 1e-12 over 1 s (the direct solve of zero rows crashed in LAPACK)."""
    scene = scene_from_dict({"robot": {"name": "double_pendulum"}, "initial": {"q": {"joint1": 0.5}}})
    general = simulate(scene, duration=1.0, solver="proxsuite", progress=False)
    native = simulate(scene, duration=1.0, progress=False)
    assert general.info.path == "general" and native.info.path == "native"
    assert set(general.info.solver_statistics.status_counts) == {"cholesky"}
    np.testing.assert_allclose(general.q, native.q, rtol=0, atol=1e-12)
