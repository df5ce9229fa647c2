"""Servoconstraints (docs/mathematics.md section 5): a virtual constraint on the double pendulum against the
partial-feedback-linearization control computed from Pinocchio's M and h, the two-car exact answer,
rank loss of the decoupling matrix detected (at a configuration, and when a run passes it), controls
within limits, refusals."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pinocchio as pin
import pytest

from conftest import ROBOTS
from pinstab import Actuation, ConstrainedModel, HolonomicConstraint, assemble, load_scene, simulate
from pinstab import scene as scene_module
from pinstab.cli import main
from pinstab.errors import SceneError, ServoInfeasibleError, ZeroDynamicsWarning
from pinstab.scene import scene_from_dict
from pinstab.system import build_system

M1, M2, K = 1.0, 2.0, 10.0


def coupling_scene(q2: float, amplitude: float = 0.0) -> dict:
    """joint1 + 0.55 joint2 = 0.55 q2 + amplitude sin 2t, realized by the elbow (joint2) alone."""
    return {
        "robot": {"name": "double_pendulum"},
        "servos": [
            {
                "name": "coupling",
                "kind": "joint-relation",
                "joints": {"joint1": 1.0, "joint2": 0.55},
                "value": 0.55 * q2,
                "sine": {"amplitude": amplitude, "omega": 2.0},
            }
        ],
        "actuation": {"joints": ["joint2"]},
        "initial": {"q": {"joint2": q2}},
    }


def singular_elbow_angle() -> float:
    """joint2 [rad] where M12 = 0.55 M11 (the coupling's decoupling vanishes), by bisection on Pinocchio's M."""
    scene = load_scene("double-pendulum-servo")
    model, data = scene.model, scene.model.createData()

    def gap(q2: float) -> float:
        mass = pin.crba(model, data, np.array([0.0, q2]))
        return 0.55 * mass[0, 0] - mass[0, 1]

    low, high = 1.0, 3.0
    assert gap(low) * gap(high) < 0
    for _ in range(200):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if gap(low) * gap(middle) > 0 else (low, middle)
    return 0.5 * (low + high)


def test_virtual_constraint_is_held_by_the_pfl_torque():
    """Acceptance: joint2 + 0.5 joint1 = 0.3 sin 2t held within 1e-9 rad over 5 s; u equals the partial
    feedback linearization u = (c'' + S M^-1 h) / (S M^-1 B) from Pinocchio's M and h at every sample
    (1e-6 relative: the run's Baumgarte term acts on a 1e-12 rad residual), while the free shoulder whirls
    (ZeroDynamicsWarning: tests/test_servo_targets.py)."""
    scene = load_scene("double-pendulum-servo")
    with pytest.warns(ZeroDynamicsWarning, match="joint1 reached"):
        trajectory = simulate(scene, integrator="rk4", dt=1e-3, duration=5.0, progress=False)
    figures = trajectory.servo_figures
    assert np.nanmax(figures["servo_error"]) <= 1e-9
    model, data = scene.model, scene.model.createData()
    row, push = np.array([0.5, 1.0]), np.array([0.0, 1.0])
    for k in range(0, len(trajectory.t), 250):
        t, q, v = trajectory.t[k], trajectory.q[k], trajectory.v[k]
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        bias = pin.nonLinearEffects(model, data, q, v)
        target = -0.3 * 4.0 * np.sin(2.0 * t)
        expected = (target + row @ np.linalg.solve(mass, bias)) / (row @ np.linalg.solve(mass, push))
        assert figures["controls"][k, 0] == pytest.approx(expected, rel=1e-6, abs=1e-9)
    assert trajectory.info.controls == ["joint2"] and np.abs(trajectory.multipliers).max() == 0.0


def test_two_cars_control_is_the_exact_formula(capsys):
    """Acceptance: y = x2 = sin t; u(t) = (m1 + m2) y'' + (m1 m2 / k) y'''' = -2.8 sin t within 1e-8 relative
    (of its amplitude) over 5 s, and car 2 follows sin t to 1e-9 m."""
    scene = load_scene("two-cars")
    trajectory = simulate(scene, integrator="rk4", dt=1e-3, duration=5.0, progress=False)
    formula = (M1 + M2) * -np.sin(trajectory.t) + M1 * M2 / K * np.sin(trajectory.t)
    np.testing.assert_allclose(trajectory.servo_figures["controls"][:, 0], formula, rtol=0, atol=2.8e-8)
    np.testing.assert_allclose(trajectory.q[:, 1], np.sin(trajectory.t), rtol=0, atol=1e-9)
    assert main(["servo", "two-cars", "--duration", "1", "--json", "--quiet"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["controls"]["x1"]["max_abs"] == pytest.approx(2.8 * np.sin(1.0), rel=1e-6)
    assert result["max_servo_error"] <= 1e-9


def test_prescribing_car2_directly_is_refused_naming_it():
    """x2 = sin t itself: the force on car 1 does not reach car 2's acceleration (S M^-1 B = 0, relative
    degree 4): ServoInfeasibleError at t = 0 naming the constraint and the direction."""
    data = {
        "robot": {"urdf": "urdf/two-cars.urdf"},
        "servos": [
            {
                "name": "follow",
                "kind": "joint-relation",
                "joints": {"x2": 1.0},
                "sine": {"amplitude": 1.0, "omega": 1.0},
            }
        ],
        "actuation": {"joints": ["x1"]},
        "forces": [
            {
                "name": "spring",
                "kind": "spring-damper",
                "frame_a": "car1",
                "frame_b": "car2",
                "stiffness": K,
                "rest_length": 1.0,
            }
        ],
        "initial": {"v": {"x2": 1.0}},
    }
    scene = scene_from_dict(data, base_dir=ROBOTS)
    with pytest.raises(
        ServoInfeasibleError,
        match=r"servo 'follow' cannot be realized at t = 0 s \(the scene's initial state\): "
        r"no control reaches the direction [+-]1 \* follow\[0\]",
    ) as info:
        simulate(scene, duration=0.1, progress=False)
    assert info.value.constraints == ["follow"] and info.value.time == 0.0


def test_rank_loss_at_a_configuration_is_detected_with_the_state(capsys, tmp_path):
    """At joint2 = q2* (M12 = 0.55 M11) the coupling's decoupling is zero: ``pinstab servo --check`` exits 2
    at t = 0 naming the constraint and the direction; a little away from it, it passes and reports D."""
    q2 = singular_elbow_angle()
    scene = scene_from_dict(coupling_scene(q2))
    system = build_system(scene)
    start = assemble(system.model, scene.q0, scene.v0)
    with pytest.raises(ServoInfeasibleError, match=r"servo 'coupling' cannot be realized at t = 0 s") as info:
        system.dynamics(start.q, start.v, 0.0)
    assert info.value.q[1] == pytest.approx(q2, abs=1e-12) and abs(info.value.direction[0]) == pytest.approx(1.0)
    path = tmp_path / "coupling.toml"
    path.write_text(
        f'[robot]\nname = "double_pendulum"\n[[servos]]\nname = "coupling"\nkind = "joint-relation"\n'
        f'joints = {{ joint1 = 1.0, joint2 = 0.55 }}\nvalue = {0.55 * q2!r}\n[actuation]\njoints = ["joint2"]\n'
        f"[initial]\nq = {{ joint2 = {q2!r} }}\n"
    )
    assert main(["servo", str(path), "--check"]) == 2
    assert (
        "servo 'coupling' cannot be realized at t = 0 s (the scene's initial state): no control reaches the direction"
        in capsys.readouterr().err
    )
    path.write_text(path.read_text().replace(f"joint2 = {q2!r}", f"joint2 = {q2 - 0.2!r}"))
    assert main(["servo", str(path), "--check", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["realizable"] is True


def test_a_run_that_passes_the_singular_configuration_stops_there():
    """Started beyond q2* with the coupling swinging: the run stops with ServoInfeasibleError when the
    decoupling's determinant changes sign (it was singular in between), with the state there."""
    q2 = singular_elbow_angle()
    with pytest.raises(ServoInfeasibleError, match=r"its determinant changed sign since t = ") as info:
        simulate(
            scene_from_dict(coupling_scene(2.5, amplitude=0.5)), integrator="rk4", dt=1e-3, duration=5.0, progress=False
        )
    assert 0 < info.value.time < 5.0 and abs(info.value.q[1] - q2) < 0.1


def test_controls_within_limits_or_refused():
    """The two-car force limited to |u| <= 2 N (it needs 2.8 N): refused naming the control and its bound;
    a user servo through the API realizes the same program when the limit allows."""
    scene = load_scene("two-cars")
    scene.actuation = Actuation(scene.actuation.matrix, ("x1",), np.array([-2.0]), np.array([2.0]))
    with pytest.raises(
        ServoInfeasibleError, match=r"within the control limits: it needs x1 = -?2\.\d+ outside \[-2, 2\]"
    ):
        simulate(scene, integrator="rk4", dt=1e-3, duration=5.0, progress=False)


def test_servo_through_the_api():
    """Scene.add_servo with a user HolonomicConstraint gives the same control as the scene's joint-relation."""
    scene = load_scene("two-cars")
    scene.constraints = [c for c in scene.constraints if not c.prescribed]
    scene.add_servo(
        HolonomicConstraint(
            "program",
            1,
            residual=lambda q, t: np.array([q[0] - 0.8 * np.sin(t)]),
            jacobian=lambda q, t: np.array([[1.0, 0.0]]),
            drift=lambda q, v, t: np.array([0.8 * np.sin(t)]),
            nv=2,
            time_derivative=lambda q, t: np.array([-0.8 * np.cos(t)]),
        )
    )
    trajectory = simulate(scene, integrator="rk4", dt=1e-3, duration=1.0, progress=False)
    np.testing.assert_allclose(trajectory.servo_figures["controls"][:, 0], -2.8 * np.sin(trajectory.t), atol=3e-8)


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        ({"actuation": None}, r"\[\[servos\]\] need controls to realize them: add an \[actuation\] table"),
        ({"actuation": {"joints": ["x3"]}}, r"actuation.joints: unknown joint 'x3'"),
        ({"actuation": {"joints": ["x1"], "matrix": [[1.0], [0.0]]}}, r"give exactly one of 'joints'"),
        ({"actuation": {"matrix": [[1.0]]}}, r"actuation.matrix must have nv = 2 rows"),
        ({"actuation": {"joints": ["x1"], "lower": [1.0], "upper": [0.0]}}, r"every lower bound must be below"),
    ],
)
def test_bad_actuation_is_named(change, pattern):

    from conftest import ROBOTS

    data = tomllib.loads((ROBOTS / "two-cars.toml").read_text())
    for key, value in change.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = value
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(data, base_dir=ROBOTS)


def panda_tracing(redundancy_fixed: bool) -> dict:
    """The Panda (fingers locked), all 7 joints actuated, its flange tracing a 5 cm circle in the y-z plane
    (frame-path servo, 1 rad/s) with its orientation held (frame-orientation servo): 6 rows, 7 controls;
    with ``redundancy_fixed`` also panda_joint3 held (joint-relation servo): 7 rows, square."""
    servos = [
        {
            "name": "trace",
            "kind": "frame-path",
            "frame": "panda_link8",
            "amplitude": [0.0, 0.05, 0.05],
            "phase": [0.0, 0.0, 1.5707963267948966],
            "omega": 1.0,
        },
        {"name": "level", "kind": "frame-orientation", "frame": "panda_link8"},
    ]
    if redundancy_fixed:
        servos.append({"name": "elbow", "kind": "joint-relation", "joints": {"panda_joint3": 1.0}})
    joints = [f"panda_joint{i}" for i in range(1, 8)]
    start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
    return {
        "robot": {"name": "panda", "locked_joints": ["panda_finger_joint1", "panda_finger_joint2"]},
        "servos": servos,
        "actuation": {"joints": joints},
        "initial": {
            "q": {**dict(zip(joints, start, strict=True)), "panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
        },
    }


def test_panda_flange_traces_a_circle_level():
    """7 prescribed rows (circle, orientation, joint 3), 7 controls: the flange follows the circle to 1e-9 m
    and keeps its orientation to 1e-9 rad over 2 s, within the URDF's torque limits."""
    scene = scene_from_dict(panda_tracing(redundancy_fixed=True))
    trajectory = simulate(scene, integrator="rk4", dt=1e-3, duration=2.0, progress=False)
    assert np.nanmax(trajectory.servo_figures["servo_error"]) <= 1e-9
    system = build_system(scene)
    kin = system.model.kin
    kin.update_positions(trajectory.q[-1])
    trace = scene.constraints[0]
    np.testing.assert_allclose(kin.placement(trace.frame).translation, trace.target(2.0)[0], atol=1e-9)
    assert np.all(np.abs(trajectory.servo_figures["controls"]) <= scene.actuation.upper)


def test_excess_controls_take_the_least_effort():
    """6 prescribed rows, 7 controls: the controls are the least-norm solution of D u = r, i.e. u lies in the
    row space of the decoupling matrix (its part orthogonal to it <= 1e-9 |u|), and they realize the rows
    (S a = rhs to 1e-9)."""
    scene = scene_from_dict(panda_tracing(redundancy_fixed=False))
    system = build_system(scene)
    start = assemble(system.model, scene.q0, scene.v0)
    evaluation = system.dynamics(start.q, start.v, 0.0)
    decoupling = system.servo.decoupling(system.model.kin.mass_matrix, evaluation.values.jacobian)[0]
    basis = np.linalg.svd(decoupling)[2][: decoupling.shape[0]]
    u = evaluation.controls
    assert decoupling.shape == (6, 7)
    assert np.linalg.norm(u - basis.T @ (basis @ u)) <= 1e-9 * np.linalg.norm(u)
    values = evaluation.values
    assert np.abs(values.jacobian @ evaluation.acceleration + values.drift).max() < 1e-9


def test_frame_targets_rows_are_derivatives():
    """frame-path and frame-orientation: G = d phi/dq and g_t = d phi/dt by central differences (1e-6), at a
    configuration off the target."""
    scene = scene_from_dict(panda_tracing(redundancy_fixed=True))

    model = ConstrainedModel(scene)
    rng = np.random.default_rng(3)
    q = pin.integrate(scene.model, scene.q0, 0.2 * rng.standard_normal(scene.model.nv))
    t, h = 0.7, 1e-6
    for constraint in scene.constraints:
        model.kin.update_jacobians(q)
        jacobian, time_term = constraint.velocity_terms(model.kin, q, t)
        columns = []
        for i in range(scene.model.nv):
            step = np.zeros(scene.model.nv)
            step[i] = h
            values = []
            for sign in (1.0, -1.0):
                moved = pin.integrate(scene.model, q, sign * step)
                model.kin.update_positions(moved)
                values.append(constraint.residual(model.kin, moved, t))
            columns.append((values[0] - values[1]) / (2 * h))
        np.testing.assert_allclose(jacobian, np.array(columns).T, atol=1e-6)
        model.kin.update_positions(q)
        rate = (constraint.residual(model.kin, q, t + h) - constraint.residual(model.kin, q, t - h)) / (2 * h)
        np.testing.assert_allclose(time_term, rate, atol=1e-6)


def test_pinstab_servo_loads_its_scene_once(monkeypatch, capsys):
    """`pinstab servo` reads the scene file once (it used to load it again to run it)."""
    loads = []
    original = scene_module.load_scene
    monkeypatch.setattr(scene_module, "load_scene", lambda *a, **k: loads.append(a) or original(*a, **k))
    assert main(["servo", "two-cars", "--duration", "0.01", "--quiet", "--json"]) == 0
    assert len(loads) == 1 and json.loads(capsys.readouterr().out)["max_reaction"] == 0.0
