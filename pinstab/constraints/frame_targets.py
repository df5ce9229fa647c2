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
from ..kernels import RowBlock
from ..tables import SceneTables
from .base import CONSTRAINT_KINDS, BlockRows
from .targets import TargetContext, TargetTrajectory, read_trajectory, sinusoid, values_at

SINE_PATH_KEYS = {"centre", "amplitude", "omega", "phase"}
PATH_KEYS = {"name", "kind", "frame", "offset", "path"} | SINE_PATH_KEYS
ORIENTATION_KEYS = {"name", "kind", "frame"}
POSE_KEYS = {"name", "kind", "frame", "offset", "rpy", "path", "axis", "turn"}
FRAME_TARGET = 7  # the compiled row kind (cpp/core_rows.hpp RowKind::frame_target)
POSITION_ROWS, ROTATION_ROWS = np.arange(3, dtype=np.int32), np.arange(3, 6, dtype=np.int32)  # of the weld's six
HELD = {"kind": "sinusoid", "wave": np.zeros(4)}  # a compiled target of value 0: no turn
Z_AXIS = np.array([0.0, 0.0, 1.0])


class FrameTarget(BlockRows):
    """A weld's rows between ``frame`` and a placement moving in time, (p(t), R_d(t) = exp(turn(t) axis) R_0), computed
    by the compiled core (``cpp/core_rows.hpp``, kind ``frame_target``): ``p - p(t)`` [m] (world axes) and
    ``log3(R_d(t)^T R)`` [rad], the ``components`` of the six. A target without a compiled form
    (:meth:`~pinstab.constraints.targets.TargetTrajectory.compiled`) hands its values at each time from its Python
    ``evaluate`` to the same rows (:func:`~pinstab.constraints.targets.values_at`), and a scene with it runs on the
    general path (:meth:`compiled_rows` is None).

    Args:
        name, kind: the constraint's. frame: its frame id. components: of the weld's six rows (0-2 position, 3-5
            rotation). start: R_0 (its rotation). path: p(t) [m] (3 components), or None (the rows read no position).
        turn: turn(t) [rad] (1 component), or None (held at 0). axis: the turn's world axis (unit).
    """

    holonomic = True

    def __init__(
        self,
        name: str,
        kind: str,
        frame: int,
        components: np.ndarray,
        start: pin.SE3,
        path: TargetTrajectory | None = None,
        turn: TargetTrajectory | None = None,
        axis: np.ndarray = Z_AXIS,
    ) -> None:
        self.name, self.kind, self.frame, self.components = name, kind, frame, components
        self.rows = len(components)
        self.path, self.turn, self.axis, self.start_rotation = path, turn, np.asarray(axis, float), start.rotation
        self._block: RowBlock | None = None  # built at first use
        self._compiled = False  # the block holds the targets' compiled forms
        self._given_at: float | None = None  # else: the time their values (from Python) were last given

    def compiled_rows(self) -> RowBlock | None:
        """The rows in the compiled core (``cpp/core_rows.cpp``), which computes them for Python too; None when a
        target has no compiled form."""
        block = self.block_at()
        return block if self._compiled else None

    def _forms(self, t: float | None) -> tuple[list, dict] | None:
        """The compiled forms of p(t) (none without a path) and turn(t): the trajectories' own (``t`` None; None
        when one has none), or their values at ``t`` [s] from Python."""
        path = [] if self.path is None else self._given(self.path, t)
        turn = [HELD] if self.turn is None else self._given(self.turn, t)
        if any(form is None for form in path + turn):
            return None
        return path, turn[0]

    @staticmethod
    def _given(trajectory: TargetTrajectory, t: float | None) -> list:
        if t is None:
            return [trajectory.compiled(component) for component in range(trajectory.size)]
        value, rate, curvature = trajectory.evaluate(t)
        return [values_at(t, *(float(x[k]) for x in (value, rate, curvature))) for k in range(trajectory.size)]

    def block_at(self, t: float | None = None) -> RowBlock:
        """The compiled rows: with the targets' compiled forms, or with their values at ``t`` [s]."""
        if self._block is None:
            placement = np.eye(4)
            placement[:3, :3] = self.start_rotation
            self._block = RowBlock(FRAME_TARGET, self.frame, -1, placement, np.zeros((0, 3)))
            forms = self._forms(None)
            self._compiled = forms is not None
            if forms is not None:
                self._block.set_frame_target(self.components, *forms, self.axis)
        if not self._compiled and t is not None and t != self._given_at:
            self._block.set_frame_target(self.components, *self._forms(t), self.axis)
            self._given_at = t
        return self._block


class FramePath(FrameTarget):
    """``p_frame - p(t)`` [m], world axes; multipliers: the force on the frame's body [N], world axes."""

    def __init__(self, name: str, frame: int, path: TargetTrajectory) -> None:
        super().__init__(name, "frame-path", frame, POSITION_ROWS, pin.SE3.Identity(), path)
        self.force_frame = "world axes, force on the frame's body"

    def target(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p, dp/dt, d2p/dt2) at time t [s]: [m, m/s, m/s^2]."""
        return self.path.evaluate(t)


class FrameOrientation(FrameTarget):
    """``log3(R_0^T R)`` [rad] of the frame's rotation R against its start orientation R_0 (a weld's rotation
    rows); the multipliers are the moment on the frame's body [N m] (in the log's axes)."""

    def __init__(self, name: str, frame: int, start: pin.SE3) -> None:
        super().__init__(name, "frame-orientation", frame, ROTATION_ROWS, start)
        self.force_frame = "moment on the frame's body, log3(R_0^T R) axes"


class FramePose(FrameTarget):
    """A frame following a placement: ``p - p(t)`` [m] (world axes), then ``log3(R_d(t)^T R)`` [rad] with
    ``R_d(t) = exp(theta(t) axis) R_0``; multipliers: the force [N] (world axes) and the moment [N m] (log
    axes) on the frame's body."""

    def __init__(
        self, name: str, frame: int, path: TargetTrajectory, axis: np.ndarray, turn: TargetTrajectory, start: pin.SE3
    ) -> None:
        rows = np.concatenate([POSITION_ROWS, ROTATION_ROWS])
        super().__init__(name, "frame-pose", frame, rows, start, path, turn, axis)
        self.force_frame = "world axes (force on the frame's body) + log3(R_d^T R) axes (moment)"


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
    axis = tables.direction(entry.get("axis", list(Z_AXIS)), f"{where}.axis")
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
