"""``external-force``: a constant force (and moment) in world axes applied at a point of a body."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..kernels import wrench_force
from ..kinematics import Kinematics
from ..tables import SceneTables
from .base import FORCE_KINDS, ForceElement, bounded_load

EXTERNAL_KEYS = {"name", "kind", "frame", "offset", "force", "moment"}


class ExternalForce(ForceElement):
    """A constant wrench on a body: ``tau = J_p^T f + J_w^T m`` with the frame's world-aligned Jacobian, computed by
    the compiled core's rule (``cpp/grasp_forces.cpp`` ``add_wrench``, which its core kernel runs too).

    Args:
        name: element name. frame: the operational frame at the point of application.
        force: [N], world axes. moment: [N m], world axes.
    """

    def __init__(self, name: str, frame: int, force: np.ndarray, moment: np.ndarray) -> None:
        self.name, self.frame = name, frame
        self.wrench = np.concatenate([np.asarray(force, float), np.asarray(moment, float)])

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        return wrench_force(kin.model, kin.data, self.frame, self.wrench)

    def compiled_form(self, rows: Mapping[str, slice]) -> dict[str, Any]:
        return {"kind": "wrench", "frame": self.frame, "wrench": self.wrench}


@FORCE_KINDS.register("external-force", summary="a constant world-axes force [N] and moment [N m] at a body point")
def parse_external_force(entry: dict, tables: SceneTables, name: str, where: str) -> ExternalForce:
    """Scene table: ``frame`` + ``offset`` [m], ``force`` [N] and ``moment`` [N m] in world axes, each of length
    at most 1e12 (:func:`~pinstab.forces.base.bounded_load`)."""
    tables.check_keys(entry, EXTERNAL_KEYS, where)
    frame = tables.attached_frame(entry, "frame", "offset", "rpy", f"{name}/point", where)
    force = tables.vector(entry.get("force", [0.0, 0.0, 0.0]), 3, f"{where}.force", "force")
    moment = tables.vector(entry.get("moment", [0.0, 0.0, 0.0]), 3, f"{where}.moment", "torque")
    bounded_load(force, f"{where}.force", "N")
    bounded_load(moment, f"{where}.moment", "N m")
    return ExternalForce(name, frame, force, moment)
