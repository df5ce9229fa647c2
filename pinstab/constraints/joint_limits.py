"""Joint limits: the position bounds of a model's 1-DOF joints (revolute, prismatic) as unilateral rows.

A limit is one side of one joint: ``lower`` holds ``q_i - lower >= 0``, ``upper`` holds ``upper - q_i >= 0``
(the gap, [rad] or [m]). Its row is ``sign e_i`` on the joint's velocity index (sign +1 for ``lower``, -1 for
``upper``), without drift; its reaction ``sign lambda`` on the joint can only push away from the bound
(``lambda >= 0``), without friction. Bounds are the model's ``lowerPositionLimit`` / ``upperPositionLimit`` as
the robot's reader filled them: a joint with ``lower == upper`` has no limit given (a URDF joint without
``<limit lower upper>`` comes as 0, 0), an infinite bound is no limit on that side, and joints with more than
one coordinate (continuous joints, spherical, free flyers) are unlimited.

A limit's row is the compiled core's (``cpp/core_rows.hpp`` kind ``joint_limit``): its gap, rate, Jacobian and drift
are computed there for every caller (:meth:`JointLimit.gap`, :meth:`JointLimit.speed`, :class:`LimitWatch`, and a held
limit's equality row :class:`ActiveLimit`, which the core kernel evaluates with the closures).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from ..kernels import RowBlock, joint_limit_gap, joint_limit_gaps, joint_limit_rate
from .base import BlockRows

LOWER, UPPER = "lower", "upper"
START_TOLERANCE = 1e-9  # [rad or m] a start this far beyond a bound counts as on it


@dataclass(frozen=True)
class JointLimit:
    """One side of one joint's range.

    Attributes:
        joint: the joint's name. side: ``lower`` or ``upper``. index_q, index_v: the joint's coordinate and
        velocity index. bound: the limit [rad or m]. restitution: Newton's e at its impact [-].
    """

    joint: str
    side: str
    index_q: int
    index_v: int
    bound: float
    restitution: float = 0.0

    @property
    def name(self) -> str:
        """``<joint> <side>``, e.g. ``panda_joint4 upper``."""
        return f"{self.joint} {self.side}"

    @property
    def sign(self) -> float:
        """+1 for a lower limit, -1 for an upper one: the direction its reaction pushes the joint."""
        return 1.0 if self.side == LOWER else -1.0

    @cached_property
    def row(self) -> RowBlock:
        """The limit's row in the compiled core (kind 8: ``sign (q_i - bound)``, Jacobian ``sign e_i``, drift 0)."""
        indices = np.array([self.index_q], np.int32), np.array([self.index_v], np.int32)
        block = RowBlock(8, -1, -1, np.eye(4), np.zeros((0, 3)), np.array([self.sign]), *indices)
        block.bound = self.bound
        return block

    def __getstate__(self) -> dict[str, Any]:
        """The fields without the compiled row (not picklable: built again at first use)."""
        return {key: value for key, value in self.__dict__.items() if key != "row"}

    def gap(self, q: np.ndarray) -> float:
        """The distance to the bound, positive inside the range [rad or m] (the core's row residual)."""
        return joint_limit_gap(self.row, q)

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """:meth:`gap` of each row of the samples ``q`` (k, nq) [rad or m]."""
        return joint_limit_gaps([self.row], q)[:, 0]

    def speed(self, v: np.ndarray) -> float:
        """The rate of the gap [rad/s or m/s] (negative: approaching the bound): its row's ``G v``; of an
        acceleration ``a``, its ``G a`` [rad/s^2 or m/s^2] (the row has no drift)."""
        return joint_limit_rate(self.row, v)


class ActiveLimit(BlockRows):
    """A joint limit held (active): its gap kept at zero as an equality row, the core's (:attr:`JointLimit.row`);
    its multiplier is the limit's reaction [N m or N], positive when it pushes away from the bound.

    Args:
        limit: the limit held (or another one-row entry with a ``name`` and a compiled ``row``: a sticking joint
            friction, :class:`~pinstab.forces.joint_friction.JointFriction`, whose multiplier is its torque).
    """

    holonomic = True
    rows = 1

    def __init__(self, limit: JointLimit) -> None:
        self.name, self.kind, self.limit = limit.name, "joint-limit", limit
        self.force_frame = "generalized force on the joint, away from its bound [N m or N]"

    def compiled_rows(self) -> RowBlock:
        """The limit's row in the compiled core."""
        return self.limit.row


@dataclass(frozen=True)
class LimitTable:
    """A model's joint limits and the joints left unlimited.

    Attributes:
        limits: the limits, two per limited joint (lower, upper) in joint order (one where a bound is infinite).
        unlimited: joint name -> why it has no limit (``no limit given (lower = upper = 0)``, ``continuous``...).
    """

    limits: list[JointLimit]
    unlimited: dict[str, str]

    def ranges(self) -> dict[str, list[float]]:
        """Each limited joint's [lower, upper] [rad or m] (an infinite side as +/-inf)."""
        ranges: dict[str, list[float]] = {}
        for limit in self.limits:
            pair = ranges.setdefault(limit.joint, [-math.inf, math.inf])
            pair[0 if limit.side == LOWER else 1] = limit.bound
        return ranges


def check_limit_bounds(model: pin.Model) -> None:
    """Refuse a model with a joint whose lower limit is above its upper one.

    Raises:
        SceneError: naming the first such joint and its bounds.
    """
    for j in range(1, model.njoints):
        joint = model.joints[j]
        lower = model.lowerPositionLimit[joint.idx_q : joint.idx_q + joint.nq]
        upper = model.upperPositionLimit[joint.idx_q : joint.idx_q + joint.nq]
        if np.any(lower > upper):
            raise SceneError(
                f"joint {model.names[j]}: its lower limit {_listed(lower)} is above its upper limit {_listed(upper)} "
                "(a joint's <limit> needs lower <= upper; lower = upper means no limit)"
            )


def joint_limits(model: pin.Model) -> LimitTable:
    """The limits of ``model``'s 1-DOF joints (see the module), and why each other joint is unlimited."""
    limits, unlimited = [], {}
    for j in range(1, model.njoints):
        joint, name = model.joints[j], model.names[j]
        if joint.nq != 1 or joint.nv != 1:
            unlimited[name] = f"{joint.shortname()} ({joint.nq} coordinates: continuous or multi-DOF)"
            continue
        lower, upper = float(model.lowerPositionLimit[joint.idx_q]), float(model.upperPositionLimit[joint.idx_q])
        if lower == upper:
            unlimited[name] = f"no limit given (lower = upper = {lower:g})"
            continue
        sides = [(side, bound) for side, bound in ((LOWER, lower), (UPPER, upper)) if math.isfinite(bound)]
        if not sides:
            unlimited[name] = "infinite bounds"
        limits += [JointLimit(name, side, joint.idx_q, joint.idx_v, bound) for side, bound in sides]
    return LimitTable(limits, unlimited)


def check_start_inside(limits: list[JointLimit], q: np.ndarray, scene: str) -> None:
    """Refuse a start beyond a joint limit (by more than :data:`START_TOLERANCE`): the limit could only throw the
    joint back at once.

    Raises:
        SceneError: naming every joint outside, its position and its bound [rad or m], and the ways out.
    """
    outside = [f"{limit.joint} = {q[limit.index_q]:.6g} beyond its {limit.side} limit {limit.bound:.6g}"
               for limit in limits if limit.gap(q) < -START_TOLERANCE]  # fmt: skip
    if outside:
        raise SceneError(
            f"scene {scene}: the start is outside the joint limits: {'; '.join(outside)}. Start inside them "
            "(initial.q), set them aside for the scene (robot.ignore_limits = [joint names]) or for the run "
            "(--ignore-limits, simulate(limits=False))"
        )


def _listed(values: np.ndarray) -> str:
    return ", ".join(f"{x:g}" for x in values)


class LimitWatch:
    """The first joint limit a run's steps leave: fed every step's state by the stepping loop, whatever samples it
    keeps (a run keeping one sample in 50 can pass a limit and come back between two of them).

    Args:
        limits: the limits watched. slack: how far beyond a bound [rad or m] a state counts as leaving it.

    Attributes:
        left: the first limit left and when [s] (the first grid step beyond it), or None.
        time: the time [s] of a grid step (the loop's grid's, set by the loop that feeds the watch).
    """

    def __init__(self, limits: list[JointLimit], slack: float) -> None:
        self.limits = limits
        self.left: tuple[JointLimit, float] | None = None
        self.time: Callable[[int], float] = float
        self._rows = [limit.row for limit in limits]
        self._floor = -slack  # the gaps >= this

    def see(self, k: int, q: np.ndarray) -> None:
        """The state q of grid step k."""
        self.see_span(k, q[None, :])

    def see_span(self, first: int, q: np.ndarray) -> None:
        """The states (rows of q) of grid steps first, first + 1, ..."""
        if self.left is None and self.limits:
            outside = joint_limit_gaps(self._rows, q) < self._floor  # (steps, limits)
            if outside.any():
                self._leave(first, outside)

    def _leave(self, first: int, outside: np.ndarray) -> None:
        row = int(np.flatnonzero(outside.any(axis=1))[0])
        self.left = (self.limits[int(np.flatnonzero(outside[row])[0])], self.time(first + row))
