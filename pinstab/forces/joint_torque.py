"""``joint-torque``: a torque (revolute) or force (prismatic) on one joint, constant or a time table."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import SceneError
from ..kernels import CompiledTarget
from ..kinematics import Kinematics
from ..tables import SceneTables
from .base import FORCE_KINDS, ForceElement, bounded_load

TORQUE_KEYS = {"name", "kind", "joint", "torque", "table"}


class JointTorque(ForceElement):
    """A torque (revolute) or force (prismatic) on one joint DOF, its table evaluated by the compiled core's target
    (``cpp/targets.cpp``, which its core kernel runs too: ``cpp/core_kernel.cpp`` add_joint_torques).

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
        return self._times

    @times.setter
    def times(self, times: np.ndarray) -> None:
        self.set_table(times, self._values)

    @property
    def values(self) -> np.ndarray:
        """Table values [N m or N] (read-only; :meth:`set_table` or assignment replaces the table)."""
        return self._values

    @values.setter
    def values(self, values: np.ndarray) -> None:
        self.set_table(self._times, values)

    def set_table(self, times: np.ndarray, values: np.ndarray) -> None:
        """Replace the table and recompile it (an edit of the arrays in place would not reach the compiled copy,
        so they are stored read-only).

        Args:
            times: table times [s], strictly increasing.
            values: table values [N m or N], one per time.

        Raises:
            SceneError: naming the element when the lengths differ, the times do not increase, or an entry is not
                finite.
        """
        times, values = np.array(times, float, ndmin=1), np.array(values, float, ndmin=1)
        if times.shape != values.shape or times.ndim != 1 or times.size == 0:
            raise SceneError(
                f"joint-torque '{self.name}': the table needs one value per time, got {times.shape} times and "
                f"{values.shape} values"
            )
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(values))):
            raise SceneError(f"joint-torque '{self.name}': the table's times and values must be finite")
        if np.any(np.diff(times) <= 0):
            raise SceneError(f"joint-torque '{self.name}': the table's times must be strictly increasing")
        times.flags.writeable = values.flags.writeable = False
        self._times, self._values = times, values
        self._table = CompiledTarget([self._compiled_table()])

    def _compiled_table(self) -> dict[str, Any]:
        """The table as a compiled piecewise polynomial (``cpp/targets.hpp``, the form of
        :func:`pinstab.constraints.targets.piecewise`): on [t_i, t_i+1) the line
        ``values_i + slope_i (t - t_i)``, from the last time on its last value (a constant piece), before the first its
        first value (held)."""
        times, values = self.times, self.values
        slopes = np.diff(values) / np.diff(times)
        coefficients = np.column_stack([values, np.append(slopes, 0.0)])
        breaks = np.append(times, np.inf)
        return {"kind": "piecewise", "breaks": breaks, "origins": times, "coefficients": coefficients, "held": True}

    def compiled_form(self, rows: Mapping[str, slice]) -> dict[str, Any]:
        """The element as the core kernel takes it (``cpp/core_kernel.hpp`` JointTorqueSpec)."""
        return {"kind": "joint-torque", "dof": int(self.dof), "torque": self._compiled_table()}

    def torque(self, t: float) -> float:
        """Applied torque at time t [N m or N]: linear between the table's points, held at its ends."""
        return float(self._table.evaluate(t)[0][0])

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
    if ("torque" in entry) == ("table" in entry):
        raise SceneError(f"{where}: give exactly one of 'torque' (constant) or 'table' ([[t, torque], ...])")
    if "torque" in entry:
        times, values = np.zeros(1), np.array([tables.quantity(entry["torque"], "torque", f"{where}.torque")])
    else:
        rows = entry["table"]
        if not isinstance(rows, list) or not rows or not all(isinstance(r, list) and len(r) == 2 for r in rows):
            raise SceneError(f"{where}.table must be a non-empty list of [time, torque] pairs")
        times = np.array([tables.quantity(r[0], "time", f"{where}.table time") for r in rows])
        values = np.array([tables.quantity(r[1], "torque", f"{where}.table torque") for r in rows])
    for k, value in enumerate(values):
        bounded_load(value, f"{where}.torque" if "torque" in entry else f"{where}.table[{k}] torque", "N m or N")
    return JointTorque(name, joint.idx_v, model.nv, times, values)
