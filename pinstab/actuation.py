"""Actuation of a scene: the matrix B (nv x k) through which controls u enter the dynamics,
``M a + h = tau + B u + G^T lambda`` (docs/mathematics.md section 5), with the controls' names and limits.

Scene table ``[actuation]``: ``joints = [...]`` (each a 1-DOF joint: u is its torque [N m] or force [N];
limits from the robot file's effort limits, :func:`effort_bounds`), or ``matrix = [[...], ...]`` (nv rows, k
columns, in the model's velocity order) with ``names``; optional ``lower`` / ``upper`` (k numbers, [N m or N])
override the limits. The matrix entries (transmission ratios [-] or lever arms [m]) and the bounds are at most
:data:`~pinstab.units.MAX_MAGNITUDE` in size, each named when beyond.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from .errors import SceneError
from .tables import check_keys, joint_id, table, unit, vector
from .units import MAX_MAGNITUDE, within_ceiling

ACTUATION_KEYS = {"joints", "matrix", "names", "lower", "upper"}


@dataclass(frozen=True)
class Actuation:
    """B (nv x k), the controls' names, and their bounds [N m or N] (+-inf where none)."""

    matrix: np.ndarray
    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    @property
    def count(self) -> int:
        """k, the number of controls."""
        return self.matrix.shape[1]


def read_actuation(value: Any, model: pin.Model) -> Actuation | None:
    """The scene's ``[actuation]`` table (None when absent)."""
    if value is None:
        return None
    entry = table(value, "actuation")
    check_keys(entry, ACTUATION_KEYS, "actuation")
    if ("joints" in entry) == ("matrix" in entry):
        raise SceneError("actuation: give exactly one of 'joints' (actuated joints) or 'matrix' (B, nv x k)")
    if "joints" in entry:
        matrix, names, lower, upper = _joint_actuation(entry["joints"], model)
    else:
        matrix, names = _matrix_actuation(entry, model)
        lower, upper = np.full(len(names), -np.inf), np.full(len(names), np.inf)
    for key in ("lower", "upper"):
        if key in entry:
            bound = _within_ceiling(
                vector(entry[key], len(names), f"actuation.{key}", None), f"actuation.{key}", "N m or N"
            )
            lower, upper = (bound, upper) if key == "lower" else (lower, bound)
    if np.any(lower >= upper):
        raise SceneError(f"actuation: every lower bound must be below its upper bound, got {lower} and {upper}")
    return Actuation(matrix, names, lower, upper)


def _joint_actuation(joints: Any, model: pin.Model) -> tuple[np.ndarray, tuple[str, ...], np.ndarray, np.ndarray]:
    if not isinstance(joints, list) or not joints or len(set(map(str, joints))) != len(joints):
        raise SceneError(f"actuation.joints must be a non-empty list of distinct joint names, got {joints!r}")
    matrix = np.zeros((model.nv, len(joints)))
    for column, name in enumerate(joints):
        joint = model.joints[joint_id(model, name, "actuation.joints")]
        if joint.nv != 1:
            raise SceneError(f"actuation.joints: joint {name!r} has {joint.nv} DOF; an actuated joint has 1")
        matrix[joint.idx_v, column] = 1.0
    lower, upper = effort_bounds(model, matrix.argmax(axis=0))  # each column's velocity coordinate
    return matrix, tuple(joints), lower, upper


def effort_bounds(model: pin.Model, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) effort bounds [N m or N] of the velocity coordinates ``indices`` as the robot file gives them
    (a URDF's ``<limit effort>``: -effort, effort; an MJCF joint's ``actuatorfrcrange``), -inf / inf where none.

    None: both bounds zero (a URDF's ``effort="0"``, which exporters write when they give none: the
    double pendulum of example-robot-data), or a bound beyond :data:`~pinstab.units.MAX_MAGNITUDE` in size (a
    URDF cannot say "no limit" on a revolute or prismatic joint, so files write a large number, and Pinocchio reads
    an absent limit as 1.8e308 or inf; 1e12 N m is past any actuator, and a bound beyond it is no bound next to
    torques of order 1 in float64).
    """
    lower = np.asarray(model.lowerEffortLimit, dtype=float)[indices]
    upper = np.asarray(model.upperEffortLimit, dtype=float)[indices]
    none = (lower == 0.0) & (upper == 0.0)
    lower = np.where(none | ~(np.abs(lower) <= MAX_MAGNITUDE), -np.inf, lower)
    upper = np.where(none | ~(np.abs(upper) <= MAX_MAGNITUDE), np.inf, upper)
    return lower, upper


def _matrix_actuation(entry: dict[str, Any], model: pin.Model) -> tuple[np.ndarray, tuple[str, ...]]:
    rows = entry["matrix"]
    if not isinstance(rows, list) or len(rows) != model.nv:
        raise SceneError(f"actuation.matrix must have nv = {model.nv} rows (one per velocity coordinate)")
    width = len(rows[0]) if isinstance(rows[0], list) else 0
    if width == 0:
        raise SceneError("actuation.matrix rows must be non-empty lists of numbers")
    matrix = np.array(
        [_within_ceiling(vector(row, width, f"actuation.matrix[{i}]", None), f"actuation.matrix[{i}]", "[-] or m")
         for i, row in enumerate(rows)]
    )  # fmt: skip
    names = entry.get("names", [f"u{i}" for i in range(width)])
    if not isinstance(names, list) or len(names) != width or not all(isinstance(n, str) for n in names):
        raise SceneError(f"actuation.names must be {width} strings, one per column of the matrix")
    for column, name in enumerate(names):
        if not np.any(matrix[:, column]):
            raise SceneError(f"actuation.matrix: column {column} ({name!r}) is zero: that control acts on nothing")
    # each column scaled to length 1: the rank asks whether the controls act in independent directions, whatever
    # the units of each (matrix_rank's tolerance grows with the largest entry, and would count a column of 1 next to
    # one of 1e12 as dependent)
    if np.linalg.matrix_rank(np.column_stack([unit(c) for c in matrix.T])) < width:
        raise SceneError("actuation.matrix: its columns are dependent (two controls act the same way)")
    return matrix, tuple(names)


def _within_ceiling(values: np.ndarray, where: str, unit_name: str) -> np.ndarray:
    """``values`` when each is at most :data:`~pinstab.units.MAX_MAGNITUDE` in size (``where[k]`` named if not)."""
    for k, value in enumerate(values):
        within_ceiling(abs(float(value)), f"|{where}[{k}]|", unit_name)
    return values
