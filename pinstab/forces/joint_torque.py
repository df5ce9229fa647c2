"""``joint-torque``: a torque (revolute) or force (prismatic) on one joint, constant or a time table."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import SceneError
from ..kinematics import Kinematics
from ..tables import SceneTables
from .base import FORCE_KINDS, ForceElement, bounded_load
from .time_table import TimeTable, read_table

TORQUE_KEYS = {"name", "kind", "joint", "torque", "table"}


class JointTorque(ForceElement):
    """A torque (revolute) or force (prismatic) on one joint DOF, its table evaluated by the compiled core's target
    (:class:`~pinstab.forces.time_table.TimeTable`; the core kernel adds it: ``cpp/core_kernel.cpp``
    add_joint_torques).

    Args:
        name: element name.
        dof: index of the joint's velocity coordinate.
        nv: velocity dimension of the model.
        times: table times [s], increasing (a single entry for a constant).
        values: table values [N m or N]; linear interpolation, held at the ends.
    """

    needs_kinematics = False

    def __init__(self, name: str, dof: int, nv: int, times: np.ndarray, values: np.ndarray) -> None:
        self.name, self.dof, self.nv = name, dof, nv
        self.set_table(times, values)

    @property
    def times(self) -> np.ndarray:
        """Table times [s] (read-only; :meth:`set_table` or assignment replaces the table)."""
        return self._table.times

    @times.setter
    def times(self, times: np.ndarray) -> None:
        self.set_table(times, self._table.values)

    @property
    def values(self) -> np.ndarray:
        """Table values [N m or N] (read-only; :meth:`set_table` or assignment replaces the table)."""
        return self._table.values

    @values.setter
    def values(self, values: np.ndarray) -> None:
        self.set_table(self._table.times, values)

    def set_table(self, times: np.ndarray, values: np.ndarray) -> None:
        """Replace the table [s], [N m or N] and recompile it (an edit of the arrays in place would not reach the
        compiled copy, so they are stored read-only).

        Raises:
            SceneError: naming the element when the lengths differ, the times do not increase, or an entry is not
                finite.
        """
        self._table = TimeTable(f"joint-torque '{self.name}'", times, values)

    def compiled_form(self, rows: Mapping[str, slice]) -> dict[str, Any]:
        """The element as the core kernel takes it (``cpp/core_kernel.hpp`` JointTorqueSpec)."""
        return {"kind": "joint-torque", "dof": int(self.dof), "torque": self._table.compiled()}

    def torque(self, t: float) -> float:
        """Applied torque at time t [N m or N]: linear between the table's points, held at its ends."""
        return self._table(t)

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        tau = np.zeros(self.nv)
        tau[self.dof] = self.torque(t)
        return tau


@FORCE_KINDS.register("joint-torque", summary="a torque on a 1-DOF joint: constant ('torque') or a time table")
def parse_joint_torque(entry: dict, tables: SceneTables, name: str, where: str) -> JointTorque:
    """Scene table: ``joint`` and either ``torque`` [N m] or ``table`` ([[t, torque], ...]), each torque's
    magnitude at most 1e12 (:func:`~pinstab.forces.base.bounded_load`)."""
    tables.check_keys(entry, TORQUE_KEYS, where)
    model = tables.model
    joint = model.joints[tables.joint_id(entry.get("joint"), f"{where}.joint")]
    if joint.nv != 1:
        raise SceneError(f"{where}: joint {entry['joint']!r} has {joint.nv} DOF; joint torques need a 1-DOF joint")
    times, values = read_table(entry, tables, "torque", "torque", where)
    for k, value in enumerate(values):
        bounded_load(value, f"{where}.torque" if "torque" in entry else f"{where}.table[{k}] torque", "N m or N")
    return JointTorque(name, joint.idx_v, model.nv, times, values)
