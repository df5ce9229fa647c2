"""The servo path (pinstab.paths.servo, cpp/servo_kernel.cpp): prescribed joint relations solved compiled, against
the general path's solve, the two-car closed form, and each target kind's evaluate (its compiled form bound alone)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pinstab import Actuation, load_scene, simulate
from pinstab.constraints.joint_relation import JointRelation
from pinstab.constraints.targets import TargetContext, read_trajectory
from pinstab.errors import ServoInfeasibleError, ZeroDynamicsWarning
from pinstab.paths.servo import ServoDynamics
from pinstab.scene import scene_from_dict
from pinstab.servo import RANK_TOLERANCE

TARGETS = {
    "polynomial": {"kind": "polynomial", "coefficients": [0.1, -0.4, 0.3, 0.05]},
    "sinusoid": {"kind": "sinusoid", "amplitude": 0.3, "omega": 2.5, "phase": 0.4, "offset": -0.2},
    "minimum-jerk": {"kind": "minimum-jerk", "from": 0.2, "to": -0.7, "start": 0.5, "duration": 1.5},
    "clamped spline": {"kind": "cubic-spline", "times": [0.3, 1.0, 1.4, 2.2], "values": [0.0, 0.5, -0.1, 0.2]},
    "natural spline": {
        "kind": "cubic-spline",
        "times": [0.3, 1.0, 1.4, 2.2],
        "values": [0.0, 0.5, -0.1, 0.2],
        "ends": "natural",
    },
}
TIMES = [0.0, 0.3, 0.45, 0.99, 1.0, 1.2, 1.9, 2.0, 2.2, 2.5, 7.0]  # [s], before, at and after the waypoints


@pytest.mark.parametrize("name", list(TARGETS))
def test_compiled_targets_equal_their_python_evaluation(name):
    """The elbow of the double pendulum servoed alone (S = B = e2): the kernel's elbow acceleration is
    c'' - Kd (v2 - c') - Kp (q2 - c) exactly, so three evaluations read c, c', c'' back; each equals the
    trajectory's own evaluate() (tests/test_target_evaluate.py checks it against closed forms) to 1e-12 (absolute,
    values of order 1) at times inside, at and beyond the pieces."""
    model = load_scene("double-pendulum-servo").model
    trajectory = read_trajectory(TARGETS[name], TargetContext(1, "coordinate", np.array([0.2])), name)
    relation = JointRelation("elbow", np.array([1.0]), np.array([1]), np.array([1]), trajectory)
    actuation = Actuation(np.array([[0.0], [1.0]]), ("joint2",), np.array([-np.inf]), np.array([np.inf]))
    kernels = {
        gains: ServoDynamics(model, [relation], actuation, *gains, RANK_TOLERANCE)
        for gains in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]
    }
    q, v, tau = np.array([0.3, 0.0]), np.array([0.1, 0.0]), np.zeros(2)
    for t in TIMES:
        curvature = kernels[0.0, 0.0].acceleration(q, v, tau, t)[1]
        value = kernels[1.0, 0.0].acceleration(q, v, tau, t)[1] - curvature
        rate = kernels[0.0, 1.0].acceleration(q, v, tau, t)[1] - curvature
        expected = [float(x[0]) for x in trajectory.evaluate(t)]
        np.testing.assert_allclose([value, rate, curvature], expected, rtol=0, atol=1e-12, err_msg=f"t = {t}")
        assert not any(kernel.unusable for kernel in kernels.values())


def test_two_cars_servo_path_meets_the_closed_form():
    """two-cars (a spring force: Python steps over the compiled solve) takes the servo path; x2 = sin t and
    x1 = 0.8 sin t to RK4's error (< 1e-11 m over 5 s), u = -2.8 sin t to 1e-9 N, and the general path's solve
    (solver 'dense') gives the same trajectory to 1e-13."""
    scene = load_scene("two-cars")
    fast = simulate(scene, duration=5.0, progress=False)
    general = simulate(scene, duration=5.0, solver="dense", progress=False)
    assert fast.info.path == "servo" and general.info.path == "general"
    assert "1 prescribed joint relation(s) realized by 1 control(s)" in fast.info.path_reason
    assert fast.info.solver_statistics.status_counts["servo"] == 4 * 5000
    assert fast.info.compiled_steps == 0  # the spring is a Python force element
    np.testing.assert_allclose(fast.q[:, 1], np.sin(fast.t), rtol=0, atol=1e-11)
    np.testing.assert_allclose(fast.q[:, 0], 0.8 * np.sin(fast.t), rtol=0, atol=1e-11)
    np.testing.assert_allclose(fast.servo_figures["controls"][:, 0], -2.8 * np.sin(fast.t), rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.q, general.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fast.v, general.v, rtol=0, atol=1e-13)


def test_double_pendulum_servo_runs_compiled_and_equals_the_general_path():
    """double-pendulum-servo (no force element) steps in the compiled loop on the servo path; over 1 s, while the
    free shoulder whirls up to ~130 rad/s, it parts from the general path's trajectory by < 1e-11 rad and its
    prescribed row holds to the general path's own error."""
    scene = load_scene("double-pendulum-servo")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ZeroDynamicsWarning)
        fast = simulate(scene, duration=1.0, progress=False)
        general = simulate(scene, duration=1.0, solver="dense", progress=False)
    assert fast.info.path == "servo" and fast.info.compiled_steps == 999  # the last step is Python's
    np.testing.assert_allclose(fast.q, general.q, rtol=0, atol=1e-11)
    row = fast.q[:, 1] + 0.5 * fast.q[:, 0] - 0.3 * np.sin(2.0 * fast.t) - (0.5 * 0.5)
    reference = general.q[:, 1] + 0.5 * general.q[:, 0] - 0.3 * np.sin(2.0 * general.t) - (0.5 * 0.5)
    assert np.abs(row).max() <= 1.01 * np.abs(reference).max() + 1e-14


def test_servos_the_kernel_cannot_take_keep_the_general_path():
    """A named solver, a servo beside a real constraint, and a method without Baumgarte's term keep the general
    path and say why."""
    scene = load_scene("two-cars")
    assert simulate(scene, duration=0.01, solver="proxsuite", progress=False).info.path == "general"
    info = simulate(scene, duration=0.01, method="mukharlyamov", progress=False).info
    assert info.path == "general" and "Baumgarte" in info.path_reason
    data = {
        "robot": {"name": "double_pendulum"},
        "servos": [{"name": "shape", "kind": "joint-relation", "joints": {"joint2": 1.0}, "value": 0.0}],
        "closures": [{"name": "gear", "kind": "joint-relation", "joints": {"joint1": 1.0}, "value": 0.0}],
        "actuation": {"joints": ["joint2"]},
    }
    info = simulate(scene_from_dict(data), duration=0.01, progress=False).info
    assert info.path == "general" and "'gear' is a real constraint beside the servos" in info.path_reason


def test_more_servo_rows_than_controls_are_refused_by_name():
    """Two prescribed joint relations and one control (D is 2 x 1): the kernel refuses every evaluation and the
    general solve raises ServoInfeasibleError at t = 0 naming the servos (no out-of-range read in the kernel)."""
    data = {
        "robot": {"name": "double_pendulum"},
        "servos": [
            {"name": "shoulder", "kind": "joint-relation", "joints": {"joint1": 1.0}, "value": 0.0},
            {"name": "elbow", "kind": "joint-relation", "joints": {"joint2": 1.0}, "value": 0.0},
        ],
        "actuation": {"joints": ["joint2"]},
    }
    with pytest.raises(ServoInfeasibleError, match=r"cannot be realized at t = 0 s.*rank 1 < 2"):
        simulate(scene_from_dict(data), duration=0.01, progress=False)
