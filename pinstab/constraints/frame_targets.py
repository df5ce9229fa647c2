"""A frame's point following a path in time, or a frame's orientation held: targets for servos (a hand
that must trace a curve, a tool kept level), usable as real constraints too.

Kinds:

* ``frame-path`` (3 rows, world axes): the point ``offset`` [m] of ``frame`` is at p(t): ``path = { kind =
  ..., ... }``, a named trajectory of 3-vectors (:mod:`pinstab.constraints.targets`; its start value is the
  point's start position), or ``p(t) = centre + amplitude * sin(omega t + phase)`` (per axis: ``amplitude``
  [m] and ``phase`` [rad] are 3-vectors, ``omega`` [rad/s] one rate; ``centre`` defaults to the point's start
  position): a line, an ellipse or a Lissajous curve.
* ``frame-orientation`` (3 rows): ``frame``'s rotation stays at its start, ``log3(R_0^T R)`` [rad].
* ``frame-pose`` (6 rows): ``frame`` follows a placement: its point on ``path`` (default: held at its start),
  its rotation ``R_d(t) = exp(theta(t) axis) R_0`` turned from its start R_0 about the fixed world ``axis``
  (default z) by the scalar trajectory ``turn`` [rad] (default: held); rows ``p - p(t)`` [m] and
  ``log3(R_d(t)^T R)`` [rad].
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from ..kernels import rotation_drift
from ..kinematics import Kinematics
from ..tables import SceneTables
from .base import CONSTRAINT_KINDS, Constraint, VelocityTerms
from .loops import FrameClosure
from .targets import TargetContext, TargetTrajectory, read_trajectory, sinusoid

SINE_PATH_KEYS = {"centre", "amplitude", "omega", "phase"}
PATH_KEYS = {"name", "kind", "frame", "offset", "path"} | SINE_PATH_KEYS
ORIENTATION_KEYS = {"name", "kind", "frame"}
POSE_KEYS = {"name", "kind", "frame", "offset", "rpy", "path", "axis", "turn"}


class FramePath(Constraint):
    """``p_frame - p(t)`` [m], world axes; multipliers: the force on the frame's body [N], world axes."""

    holonomic = True
    rows = 3

    def __init__(self, name: str, frame: int, path: TargetTrajectory) -> None:
        self.name, self.kind, self.frame, self.path = name, "frame-path", frame, path
        self.force_frame = "world axes, force on the frame's body"

    def target(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p, dp/dt, d2p/dt2) at time t [s]: [m, m/s, m/s^2]."""
        return self.path.evaluate(t)

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return kin.placement(self.frame).translation - self.target(t)[0]

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        return VelocityTerms(kin.jacobian(self.frame)[:3], -self.target(t)[1])

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return kin.drift_acceleration(self.frame).linear - self.target(t)[2]


class FrameOrientation(Constraint):
    """``log3(R_0^T R)`` [rad] of the frame's rotation R against its start orientation R_0 (a weld's rotation
    rows); the multipliers are the moment on the frame's body [N m] (in the log's axes)."""

    holonomic = True
    rows = 3

    def __init__(self, name: str, frame: int, start: pin.SE3) -> None:
        self.name, self.kind, self.frame = name, "frame-orientation", frame
        self._weld = FrameClosure(name, "weld", frame, None, start)  # its rotation rows are these rows
        self.force_frame = "moment on the frame's body, log3(R_0^T R) axes"

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return self._weld.residual(kin, q, t)[3:]

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        jacobian, time_term = self._weld.velocity_terms(kin, q, t)
        return VelocityTerms(jacobian[3:], time_term[3:])

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return self._weld.drift(kin, q, v, t)[3:]


class FramePose(Constraint):
    """A frame following a placement: ``p - p(t)`` [m] (world axes), then ``log3(R_d(t)^T R)`` [rad] with
    ``R_d(t) = exp(theta(t) axis) R_0``; multipliers: the force [N] (world axes) and the moment [N m] (log
    axes) on the frame's body."""

    holonomic = True
    rows = 6

    def __init__(
        self, name: str, frame: int, path: TargetTrajectory, axis: np.ndarray, turn: TargetTrajectory, start: pin.SE3
    ) -> None:
        self.name, self.kind, self.frame = name, "frame-pose", frame
        self._point = FramePath(name, frame, path)  # the position rows
        self.axis, self.turn, self.start_rotation = axis, turn, start.rotation
        self.force_frame = "world axes (force on the frame's body) + log3(R_d^T R) axes (moment)"

    def orientation(self, t: float) -> tuple[np.ndarray, float, float]:
        """(R_d(t), theta rate [rad/s], theta acceleration [rad/s^2]) at time t [s]."""
        angle, rate, acceleration = (float(x[0]) for x in self.turn.evaluate(t))
        return pin.exp3(angle * self.axis) @ self.start_rotation, rate, acceleration

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        rotation = self.orientation(t)[0]
        error = pin.log3(rotation.T @ kin.placement(self.frame).rotation)
        return np.concatenate([self._point.residual(kin, q, t), error])

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        linear = self._point.velocity_terms(kin, q, t)
        rotation, rate, _ = self.orientation(t)
        actual = kin.placement(self.frame).rotation
        turned = pin.Jlog3(rotation.T @ actual) @ actual.T  # d log3 / dt = turned (omega - rate axis)
        jacobian = np.vstack([linear.jacobian, turned @ kin.jacobian(self.frame)[3:]])
        return VelocityTerms(jacobian, np.concatenate([linear.time_term, -rate * turned @ self.axis]))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        rotation, rate, acceleration = self.orientation(t)
        angular = kin.drift_acceleration(self.frame).angular - acceleration * self.axis
        omega = kin.velocity(self.frame).angular
        turning = rotation_drift(kin.placement(self.frame).rotation, rotation, omega, rate * self.axis, angular)
        return np.concatenate([self._point.drift(kin, q, v, t), turning])


def parse_frame_path(entry: dict, tables: SceneTables, name: str, where: str) -> FramePath:
    """Scene table: ``frame`` + ``offset`` [m]; ``path`` (a trajectory table), or ``centre`` [m] (default: the
    point's start), ``amplitude`` [m] and ``phase`` [rad] (3 each), ``omega`` [rad/s]."""
    tables.check_keys(entry, PATH_KEYS, where)
    frame = tables.attached_frame(entry, "frame", "offset", "rpy", f"{name}/point", where)
    context = TargetContext(3, "length", tables.initial_placement(frame).translation, tables.within_reach)
    if "path" not in entry:
        sine = {key: entry[key] for key in SINE_PATH_KEYS & set(entry)}
        if "centre" in sine:
            sine["offset"] = sine.pop("centre")
        return FramePath(name, frame, sinusoid(sine, context, where))
    given = sorted(SINE_PATH_KEYS & set(entry))
    if given:
        raise SceneError(f"{where}: give either 'path' or {', '.join(repr(k) for k in given)}, not both")
    return FramePath(name, frame, read_trajectory(entry["path"], context, f"{where}.path"))


def parse_frame_pose(entry: dict, tables: SceneTables, name: str, where: str) -> FramePose:
    """Scene table: ``frame`` + ``offset`` [m] and ``rpy`` [rad]; ``path`` (3-vector trajectory, default held),
    ``axis`` (world, default z), ``turn`` (angle trajectory from 0, default held)."""
    tables.check_keys(entry, POSE_KEYS, where)
    frame = tables.attached_frame(entry, "frame", "offset", "rpy", f"{name}/frame", where)
    start = tables.initial_placement(frame)
    held = {"kind": "sinusoid"}  # of no amplitude: the start value
    context = TargetContext(3, "length", start.translation, tables.within_reach)
    path = read_trajectory(entry.get("path", held), context, f"{where}.path")
    axis = tables.direction(entry.get("axis", [0.0, 0.0, 1.0]), f"{where}.axis")
    turn = read_trajectory(entry.get("turn", held), TargetContext(1, "angle", np.zeros(1)), f"{where}.turn")
    return FramePose(name, frame, path, axis, turn, start)


def parse_frame_orientation(entry: dict, tables: SceneTables, name: str, where: str) -> FrameOrientation:
    """Scene table: ``frame`` (its start orientation is held)."""
    tables.check_keys(entry, ORIENTATION_KEYS, where)
    frame = tables.attached_frame(entry, "frame", "offset", "rpy", f"{name}/frame", where)
    return FrameOrientation(name, frame, tables.initial_placement(frame))


CONSTRAINT_KINDS.register(
    "frame-path", parse_frame_path, summary="3 rows: a frame point on a path (a trajectory, or a sinusoid per axis)"
)
CONSTRAINT_KINDS.register(
    "frame-pose", parse_frame_pose, summary="6 rows: a frame on a path, turned about a world axis by a trajectory"
)
CONSTRAINT_KINDS.register(
    "frame-orientation", parse_frame_orientation, summary="3 rows: a frame's orientation held at its start"
)
