"""Joint limits on the held path: the limits a run holds (its start inside them), the first limit a run's steps
leave (or its start moves into), and the constraints the event path (which holds the limits) cannot take."""

from __future__ import annotations

from contextlib import closing

import numpy as np

from ..constraints import RowKind
from ..constraints.joint_limits import JointLimit, LimitWatch, check_start_inside, joint_limits
from ..integration.events import LIMIT_SLACK
from ..scene import Scene
from ..solvers.contact_modes import plane_geometries
from ..solvers.mode_choice import TOUCH_GAP, TOUCH_SPEED
from ..trajectory import StreamedTrajectory, Trajectory


def held_limits(scene: Scene, q0: np.ndarray, limits: bool = True) -> list[JointLimit]:
    """The joint limits a run from ``q0`` [rad, m] holds, none when ``limits`` is False (``--ignore-limits``,
    ``simulate(limits=False)``); ``run``, ``servo`` and ``check`` refuse the same starts.

    Raises:
        SceneError: ``q0`` outside the limits (:func:`~pinstab.constraints.joint_limits.check_start_inside`).
    """
    table = joint_limits(scene.model).limits if limits else []
    check_start_inside(table, q0, scene.name)
    return table


def not_event_driven(scene: Scene) -> list[str]:
    """The constraints of a scene that the event path cannot take with joint limits: those neither event-driven
    contacts nor holonomic equality rows (servo rows, held contacts, rolling and other Pfaffian rows, which it
    would hold without their drift correction)."""
    names = {g.name for g in plane_geometries(scene.constraints)}
    return [
        c.name
        for c in scene.constraints
        if c.name not in names and (c.row_kind is not RowKind.EQUALITY or c.prescribed or not c.holonomic)
    ]


def limit_watch(limits: list[JointLimit]) -> LimitWatch:
    """The watch a run that does not hold ``limits`` is stepped with: every step beyond :data:`LIMIT_SLACK` of a
    bound counts as leaving it."""
    return LimitWatch(limits, LIMIT_SLACK)


def limit_left(
    trajectory: Trajectory | StreamedTrajectory, watch: LimitWatch, v0: np.ndarray
) -> tuple[JointLimit, float] | None:
    """The first joint limit a run's steps leave (``watch``, fed every step, kept or not) and when [s], or None. A
    limit the start ``v0`` [rad/s, m/s] moves into from on it (the trajectory's first sample within ``TOUCH_GAP``,
    faster than ``TOUCH_SPEED``) is left at the start: the joint passes it at once, though the steps may not show it
    (a force turning it back within a step: the held path would miss the impact)."""
    t0, q0 = _first_sample(trajectory)
    for limit in watch.limits:
        if limit.gap(q0) <= TOUCH_GAP and limit.speed(v0) < -TOUCH_SPEED:
            return limit, t0
    return watch.left


def _first_sample(trajectory: Trajectory | StreamedTrajectory) -> tuple[float, np.ndarray]:
    """The time [s] and q of a trajectory's first sample (a streamed run's from its file's first block)."""
    if isinstance(trajectory, StreamedTrajectory):
        with closing(trajectory.blocks()) as blocks:  # the file closed before the event path writes it again
            t, q = next(blocks)
    else:
        t, q = trajectory.t, trajectory.q
    return float(t[0]), q[0]
