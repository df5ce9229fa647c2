"""``joint-torque``: a torque (revolute) or force (prismatic) on one joint, constant or a time table."""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..kinematics import Kinematics
from ..tables import SceneTables
from .base import FORCE_KINDS, ForceElement, bounded_load

TORQUE_KEYS = {"name", "kind", "joint", "torque", "table"}


class JointTorque(ForceElement):
    """A torque (revolute) or force (prismatic) on one joint DOF.

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
        self.times, self.values = np.asarray(times, float), np.asarray(values, float)

    def torque(self, t: float) -> float:
        """Applied torque at time t [N m or N]."""
        return float(np.interp(t, self.times, self.values))

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
        if np.any(np.diff(times) <= 0):
            raise SceneError(f"{where}.table: times must be strictly increasing")
    for k, value in enumerate(values):
        bounded_load(value, f"{where}.torque" if "torque" in entry else f"{where}.table[{k}] torque", "N m or N")
    return JointTorque(name, joint.idx_v, model.nv, times, values)
