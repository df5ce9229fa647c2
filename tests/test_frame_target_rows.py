"""Frame targets' compiled rows (cpp/core_rows.cpp, RowKind::frame_target; pinstab/constraints/frame_targets.py):
each kind's G and g_t against central differences of its residual in q and t, its drift against a difference of
G v + g_t along the motion, block_rate against G v + g_t; a target without a compiled form (its values from Python)
giving the same rows; and the Panda's frame-pose and frame-path servos run to 1e-10 with the rows of the previous
Python implementation (kept here as the reference)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_servo import panda_tracing
from test_servo_targets import panda_pose

from pinstab import ConstrainedModel, simulate
from pinstab._compiled import rotation_drift
from pinstab.constraints.base import Constraint, VelocityTerms
from pinstab.constraints.frame_targets import FrameOrientation, FramePath, FramePose
from pinstab.constraints.targets import TargetTrajectory
from pinstab.kernels import block_rate
from pinstab.scene import scene_from_dict

H = 1e-6  # central-difference step [s, rad]


class PythonValues(TargetTrajectory):
    """A trajectory without a compiled form (a user's kind): its values from Python (the wrapped one's)."""

    def __init__(self, inner: TargetTrajectory) -> None:
        self.inner, self.size = inner, inner.size

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.inner.evaluate(t)


def kinds(scene) -> dict[str, Constraint]:
    """frame-pose (ellipse, minimum-jerk turn about z), and frame-path and frame-orientation on the same frame."""
    pose = scene.constraints[0]
    path = FramePath("path", pose.frame, pose.path)
    kin = ConstrainedModel(scene).kin
    kin.update_positions(scene.q0)
    orientation = FrameOrientation("level", pose.frame, kin.placement(pose.frame).copy())
    return {"frame-pose": pose, "frame-path": path, "frame-orientation": orientation}


@pytest.mark.parametrize("kind", ["frame-pose", "frame-path", "frame-orientation"])
def test_rows_are_derivatives(kind):
    """At a configuration off the target, t = 0.4 s (mid-turn): G = d phi/dq and g_t = d phi/dt, and gamma0 =
    d/ds (G v + g_t) along q + s v, t + s (the Panda's joints are revolute: zero joint acceleration), by central
    differences (1e-6) to 1e-6; block_rate = G v + g_t to 1e-12."""
    scene = scene_from_dict(panda_pose())
    constraint = kinds(scene)[kind]
    kin = ConstrainedModel(scene).kin
    nv = scene.model.nv
    rng = np.random.default_rng(11)
    q = pin.integrate(scene.model, scene.q0, 0.2 * rng.standard_normal(nv))
    v = rng.standard_normal(nv)
    t = 0.4

    def residual(q_: np.ndarray, t_: float) -> np.ndarray:
        kin.update_positions(q_)
        return constraint.residual(kin, q_, t_)

    def rate(s: float) -> np.ndarray:
        moved = q + s * v
        kin.update_jacobians(moved)
        jacobian, time_term = constraint.velocity_terms(kin, moved, t + s)
        return jacobian @ v + time_term

    kin.update_jacobians(q)
    jacobian, time_term = constraint.velocity_terms(kin, q, t)
    assert jacobian.shape == (constraint.rows, nv)
    assert kind == "frame-orientation" or np.abs(time_term).max() > 1e-3  # a moving target: g_t is checked
    columns = [(residual(q + H * e, t) - residual(q - H * e, t)) / (2 * H) for e in np.eye(nv)]
    np.testing.assert_allclose(jacobian, np.array(columns).T, atol=1e-6)
    np.testing.assert_allclose(time_term, (residual(q, t + H) - residual(q, t - H)) / (2 * H), atol=1e-6)
    kin.update(q, v)
    drift = constraint.drift(kin, q, v, t)
    np.testing.assert_allclose(drift, (rate(H) - rate(-H)) / (2 * H), atol=1e-6)
    kin.update(q, v)
    compiled = block_rate(kin.model, kin.data, constraint.compiled_rows(), v, t)
    np.testing.assert_allclose(compiled, jacobian @ v + time_term, rtol=0, atol=1e-12)


def test_python_valued_targets_give_the_same_rows():
    """A pose whose path and turn have no compiled form: no compiled rows (its scene runs on the general path), and
    its residual, G, g_t and drift equal the compiled pose's to 1e-14 at three times."""
    scene = scene_from_dict(panda_pose())
    pose = scene.constraints[0]
    start = pin.SE3(pose.start_rotation, np.zeros(3))
    python = FramePose("py", pose.frame, PythonValues(pose.path), pose.axis, PythonValues(pose.turn), start)
    assert python.compiled_rows() is None and pose.compiled_rows() is not None
    kin = ConstrainedModel(scene).kin
    rng = np.random.default_rng(2)
    q = pin.integrate(scene.model, scene.q0, 0.1 * rng.standard_normal(scene.model.nv))
    v = rng.standard_normal(scene.model.nv)
    kin.update(q, v)
    for t in (0.1, 0.5, 1.3):
        for part in ("residual", "drift"):
            args = (kin, q, v, t) if part == "drift" else (kin, q, t)
            expected = getattr(pose, part)(*args)
            np.testing.assert_allclose(getattr(python, part)(*args), expected, rtol=0, atol=1e-14)
        for got, expected in zip(python.velocity_terms(kin, q, t), pose.velocity_terms(kin, q, t), strict=True):
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)


class ReferencePose(Constraint):
    """The previous Python rows of frame-path, frame-orientation and frame-pose (pin.log3, Jlog3 and the drift of
    the rotation rows), a pose with an optional path and turn: the reference of the compiled ones."""

    holonomic = True

    def __init__(self, target: Constraint, start_rotation: np.ndarray) -> None:
        self.name, self.kind, self.frame, self.prescribed = target.name, target.kind, target.frame, True
        self.rows, self.force_frame = target.rows, target.force_frame
        self.path, self.turn = getattr(target, "path", None), getattr(target, "turn", None)
        self.axis = getattr(target, "axis", np.array([0.0, 0.0, 1.0]))
        self.start_rotation = start_rotation
        self.position, self.rotation = target.kind != "frame-orientation", target.kind != "frame-path"

    def _target(self, t: float):
        zero = np.zeros(3)
        point = self.path.evaluate(t) if self.path is not None else (zero, zero, zero)
        turn = (float(x[0]) for x in self.turn.evaluate(t)) if self.turn is not None else (0.0, 0.0, 0.0)
        angle, rate, acceleration = turn
        return point, pin.exp3(angle * self.axis) @ self.start_rotation, rate, acceleration

    def _pick(self, linear: np.ndarray, angular: np.ndarray) -> np.ndarray:
        return np.concatenate([linear] * self.position + [angular] * self.rotation)

    def residual(self, kin, q, t):
        point, rotation, _, _ = self._target(t)
        placement = kin.placement(self.frame)
        return self._pick(placement.translation - point[0], pin.log3(rotation.T @ placement.rotation))

    def velocity_terms(self, kin, q, t):
        point, rotation, rate, _ = self._target(t)
        actual = kin.placement(self.frame).rotation
        turned = pin.Jlog3(rotation.T @ actual) @ actual.T
        jacobian = kin.jacobian(self.frame)
        return VelocityTerms(
            np.vstack([jacobian[:3]] * self.position + [turned @ jacobian[3:]] * self.rotation),
            self._pick(-point[1], -rate * turned @ self.axis),
        )

    def drift(self, kin, q, v, t):
        point, rotation, rate, acceleration = self._target(t)
        motion = kin.drift_acceleration(self.frame)
        angular = motion.angular - acceleration * self.axis
        omega = kin.velocity(self.frame).angular
        turning = rotation_drift(kin.placement(self.frame).rotation, rotation, omega, rate * self.axis, angular)
        return self._pick(motion.linear - point[2], turning)


@pytest.mark.parametrize(
    "data, dt, duration", [(panda_pose(), 2e-3, 1.5), (panda_tracing(True), 1e-3, 1.0)], ids=["pose", "tracing"]
)
def test_servo_runs_as_with_the_python_rows(data, dt, duration):
    """The Panda's frame-pose servo (ellipse, 30 deg turn; 1.5 s) and frame-path + frame-orientation servos (circle,
    held level; 1 s) under RK4: q and v equal to 1e-10 to the run with the previous Python rows."""
    scene = scene_from_dict(data)
    kin = ConstrainedModel(scene).kin
    kin.update_positions(scene.q0)
    runs = [simulate(scene, integrator="rk4", dt=dt, duration=duration, progress=False)]
    for index, constraint in enumerate(scene.constraints):
        if constraint.kind.startswith("frame-"):
            start = kin.placement(constraint.frame).rotation.copy()
            scene.constraints[index] = ReferencePose(constraint, start)
    runs.append(simulate(scene, integrator="rk4", dt=dt, duration=duration, progress=False))
    assert any(isinstance(c, ReferencePose) for c in scene.constraints)
    np.testing.assert_allclose(runs[0].q, runs[1].q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(runs[0].v, runs[1].v, rtol=0, atol=1e-10)


def test_frame_pose_closure_runs_on_the_compiled_core():
    """The Panda unactuated, its flange held on the pose target as a real constraint (a closure) for 0.3 s: the
    core path takes its rows compiled (no Python rows), and its run is the general path's (ProxQP, the rows from
    Python's block_* calls) to 1e-10 in q and v (measured 1e-16, 3e-16)."""
    data = panda_pose()
    data["closures"] = [data.pop("servos")[0]]
    data.pop("actuation")
    core = simulate(scene_from_dict(data), integrator="rk4", dt=1e-3, duration=0.3, progress=False)
    general = simulate(
        scene_from_dict(data), integrator="rk4", dt=1e-3, duration=0.3, progress=False, solver="proxsuite"
    )
    assert (core.info.path, general.info.path) == ("core", "general")
    assert core.info.path_reason.startswith("1 constraint block(s) of 6 rows")
    assert "evaluated in Python" not in core.info.path_reason  # (was: "constraint(s) pose evaluated in Python")
    np.testing.assert_allclose(core.q, general.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(core.v, general.v, rtol=0, atol=1e-10)
