"""A linear relation between joint coordinates, prescribed in time: ``sum_i c_i q_i = c(t)``.

Kind ``joint-relation``: ``joints = { name = coefficient, ... }`` (1-DOF joints) and c(t) either as
``target = { kind = ..., ... }``, a named trajectory (:mod:`pinstab.constraints.targets`: polynomial,
sinusoid, minimum-jerk, cubic-spline; its start value is the relation's value at the initial
configuration), or as ``value`` [m or rad] and optionally ``sine = { amplitude, omega, phase }``:
c(t) = value + amplitude sin(omega t + phase) (omega [rad/s], phase [rad]). As a closure it couples joints
(a gear); as a servo (``[[servos]]``) it is a virtual constraint the controls realize (e.g. alpha - beta = c(t)).
"""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..kernels import RowBlock
from ..tables import SceneTables
from ..units import within_ceiling
from .base import CONSTRAINT_KINDS, BlockRows
from .targets import TargetContext, TargetTrajectory, read_trajectory, sinusoid, values_at

RELATION_KEYS = {"name", "kind", "joints", "value", "sine", "target"}
SINE_KEYS = {"amplitude", "omega", "phase"}


class JointRelation(BlockRows):
    """One holonomic row ``coefficients . q - c(t)`` [m or rad] on 1-DOF joints.

    Its ``residual_units`` are its largest and smallest nonzero |coefficient|: the residual over the largest is the
    displacement of the most geared joint that meets the relation [m or rad] (the least of one joint's, at least the
    configuration's distance from the relation): what the assembly accepts; over the smallest, that of the least
    geared joint (z2 in z2 + 1e9 z1 = 0): what it aims to bring to rounding. Both are the same for the relation
    written with its coefficients times any factor (``{a = 1, b = -1}`` and ``{a = 1e9, b = -1e9}`` are one relation).

    Args:
        name: unique name. coefficients: (nv,) row over the velocity coordinates (1-DOF joints only, so
            q's and v's indices agree through ``indices``). indices: configuration index per coefficient.
        trajectory: c(t) [m or rad] (size 1).
    """

    holonomic = True
    rows = 1

    def __init__(
        self,
        name: str,
        row: np.ndarray,
        q_indices: np.ndarray,
        v_indices: np.ndarray,
        trajectory: TargetTrajectory,
    ) -> None:
        self.name, self.kind = name, "joint-relation"
        self.row, self.q_indices, self.v_indices = row, q_indices, v_indices
        self.trajectory = trajectory
        sizes = np.abs(row[row != 0.0])
        self.residual_units = (float(np.max(sizes)), float(np.min(sizes)))
        self.force_frame = "generalized force along the relation's row [N m or N]"
        self._indices = (np.asarray(row, float), np.asarray(q_indices, np.int32), np.asarray(v_indices, np.int32))
        self._block: RowBlock | None = None  # built at first use
        self._compiled = False  # the block holds the target's compiled form
        self._given_at: float | None = None  # else: the time its values (from Python) were last given

    def compiled_rows(self) -> RowBlock | None:
        """The relation in the compiled core (``cpp/core_rows.cpp``), which computes it for Python too; None for a
        target without a compiled form (:meth:`~pinstab.constraints.targets.TargetTrajectory.compiled`)."""
        block = self.block_at()
        return block if self._compiled else None

    def block_at(self, t: float | None = None) -> RowBlock:
        """The compiled relation row: with the target's compiled form, or (a target without one) with its values at
        ``t`` [s] from its Python evaluate (:func:`~pinstab.constraints.targets.values_at`), the same row arithmetic."""
        if self._block is None:
            form = self.trajectory.compiled(0)
            self._compiled = form is not None
            self._block = RowBlock(4, -1, -1, np.eye(4), np.zeros((0, 3)), *self._indices, form)
        if not self._compiled and t is not None and t != self._given_at:
            value, rate, curvature = (float(x[0]) for x in self.trajectory.evaluate(t))
            self._block.set_target(values_at(t, value, rate, curvature))
            self._given_at = t
        return self._block


def parse_joint_relation(entry: dict, tables: SceneTables, name: str, where: str) -> JointRelation:
    """Scene table: ``joints`` {name: coefficient}; ``target`` (a trajectory table), or ``value`` and ``sine``
    {amplitude, omega, phase}."""
    tables.check_keys(entry, RELATION_KEYS, where)
    joints = entry.get("joints")
    if not isinstance(joints, dict) or not joints:
        raise SceneError(f"{where}.joints must be a table of joint names and coefficients, e.g. {{ a = 1, b = -1 }}")
    row, q_indices, v_indices = [], [], []
    for joint_name in joints:
        joint = tables.model.joints[tables.joint_id(joint_name, f"{where}.joints")]
        if joint.nv != 1 or joint.nq != 1:
            raise SceneError(f"{where}.joints: joint {joint_name!r} is not a 1-DOF joint with one coordinate")
        coefficient = tables.number(joints, joint_name, f"{where}.joints")
        # a gear or lever ratio, as actuation.matrix's entries: at most MAX_MAGNITUDE (its rows' squares, in the
        # velocity projection and the dynamics, overflow from about 1e154)
        within_ceiling(abs(coefficient), f"|{where}.joints.{joint_name}|", "[-] or m/rad")
        row.append(coefficient)
        q_indices.append(joint.idx_q)
        v_indices.append(joint.idx_v)
    if not any(row):
        raise SceneError(f"{where}.joints: every coefficient is zero")
    q_indices, v_indices = np.array(q_indices), np.array(v_indices)
    start = np.array([float(np.array(row) @ tables.q0[q_indices])])
    trajectory = _relation_target(entry, tables, TargetContext(1, "coordinate", start), where)
    return JointRelation(name, np.array(row), q_indices, v_indices, trajectory)


def _relation_target(entry: dict, tables: SceneTables, context: TargetContext, where: str) -> TargetTrajectory:
    """c(t): the ``target`` trajectory, or ``value`` + the ``sine`` table (a sinusoid about value, default 0)."""
    if "target" in entry:
        given = [key for key in ("value", "sine") if key in entry]
        if given:
            raise SceneError(f"{where}: give either 'target' or {' and '.join(repr(k) for k in given)}, not both")
        return read_trajectory(entry["target"], context, f"{where}.target")
    sine = entry.get("sine", {})
    if not isinstance(sine, dict):
        raise SceneError(f"{where}.sine must be a table {{ amplitude, omega, phase }}")
    tables.check_keys(sine, SINE_KEYS, f"{where}.sine")
    value = tables.quantity(entry.get("value", 0.0), "coordinate", f"{where}.value")
    return sinusoid({**sine, "offset": value}, context, f"{where}.sine")


CONSTRAINT_KINDS.register(
    "joint-relation",
    parse_joint_relation,
    summary="1 row: sum of coefficient x joint coordinate = c(t) (value + sine, or a target trajectory)",
)
