"""Joint limits on the held path: the limits a run holds (its start inside them), the first limit a run's samples
leave (or its start moves into), and the constraints the event path (which holds the limits) cannot take."""

from __future__ import annotations

from collections.abc import Iterable
from contextlib import closing

import numpy as np

from ..constraints import RowKind
from ..constraints.joint_limits import JointLimit, check_start_inside, joint_limits
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


def limit_left(
    trajectory: Trajectory | StreamedTrajectory, limits: list[JointLimit], v0: np.ndarray
) -> tuple[JointLimit, float] | None:
    """The first joint limit a trajectory's samples leave (beyond :data:`LIMIT_SLACK`) and when [s], or None (a
    streamed run's file read a block at a time). A limit the start ``v0`` [rad/s, m/s] moves into from on it (within
    ``TOUCH_GAP``, faster than ``TOUCH_SPEED``) is left at the first sample: the joint passes it at once, though the
    samples may not show it (a force turning it back within a step: the held path would miss the impact)."""
    if isinstance(trajectory, StreamedTrajectory):
        with closing(trajectory.blocks()) as blocks:  # the file closed before the event path writes it again
            return _first_left(blocks, limits, v0)
    return _first_left([(trajectory.t, trajectory.q)], limits, v0)


def _first_left(
    blocks: Iterable[tuple[np.ndarray, np.ndarray]], limits: list[JointLimit], v0: np.ndarray
) -> tuple[JointLimit, float] | None:
    """:func:`limit_left` over consecutive blocks of samples (t [s], q)."""
    for k, (t, q) in enumerate(blocks):
        if k == 0 and len(t):
            for limit in limits:
                if limit.gap(q[0]) <= TOUCH_GAP and limit.speed(v0) < -TOUCH_SPEED:
                    return limit, float(t[0])
        first = None
        for limit in limits:
            outside = np.flatnonzero(limit.gaps(q) < -LIMIT_SLACK)
            if outside.size and (first is None or t[outside[0]] < first[1]):
                first = (limit, float(t[outside[0]]))
        if first is not None:
            return first
    return None
