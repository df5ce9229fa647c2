"""``spring-damper``: a linear spring-damper between two frame points (or a frame point and a world point)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from ..kinematics import Kinematics
from ..tables import WORLD, SceneTables
from ..units import within_ceiling
from .base import FORCE_KINDS, ForceElement

SPRING_KEYS = {"name", "kind", "frame_a", "offset_a", "frame_b", "offset_b", "stiffness", "damping", "rest_length"}


class SpringDamper(ForceElement):
    """A linear spring-damper between two frame points (``frame_b`` None: a fixed world point).

    Force on point a: ``-(k (L - L0) + c dL/dt) u`` with ``u = (p_a - p_b)/L``.

    Args:
        stiffness: k [N/m]. damping: c [N s/m]. rest_length: L0 [m].
    """

    def __init__(
        self,
        name: str,
        frame_a: int,
        frame_b: int | None,
        world_point_b: np.ndarray,
        stiffness: float,
        damping: float,
        rest_length: float,
    ) -> None:
        self.name, self.frame_a, self.frame_b = name, frame_a, frame_b
        self.world_point_b = np.asarray(world_point_b, float)
        self.stiffness, self.damping, self.rest_length = stiffness, damping, rest_length

    def _geometry(self, kin: Kinematics) -> tuple[np.ndarray, float, np.ndarray]:
        pa = kin.placement(self.frame_a).translation
        pb = self.world_point_b if self.frame_b is None else kin.placement(self.frame_b).translation
        jac = kin.jacobian(self.frame_a)[:3]
        if self.frame_b is not None:
            jac = jac - kin.jacobian(self.frame_b)[:3]
        diff = pa - pb
        return diff, float(np.linalg.norm(diff)), jac

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        diff, length, jac = self._geometry(kin)
        if length < 1e-12:
            return np.zeros(jac.shape[1])
        direction = diff / length
        length_rate = float(direction @ (jac @ v))
        magnitude = -(self.stiffness * (length - self.rest_length) + self.damping * length_rate)
        return jac.T @ (magnitude * direction)

    def power(self, kin: Kinematics, v: np.ndarray, t: float) -> float:
        diff, length, jac = self._geometry(kin)
        if length < 1e-12:
            return 0.0
        return -self.damping * float(diff / length @ (jac @ v)) ** 2

    @property
    def stores_energy(self) -> bool:
        return self.stiffness != 0.0

    def potential_energy(self, kin: Kinematics) -> float:
        _, length, _ = self._geometry(kin)
        return 0.5 * self.stiffness * (length - self.rest_length) ** 2


@FORCE_KINDS.register("spring-damper", summary="a linear spring-damper between two points")
def parse_spring_damper(entry: dict, tables: SceneTables, name: str, where: str) -> SpringDamper:
    """Scene table: ``frame_a`` + ``offset_a``, ``frame_b`` (default world) + ``offset_b`` [m],
    ``stiffness`` [N/m], ``damping`` [N s/m], ``rest_length`` [m]."""
    tables.check_keys(entry, SPRING_KEYS, where)
    frame_a = tables.attached_frame(entry, "frame_a", "offset_a", "rpy_a", f"{name}/a", where)
    offset_b = tables.vector(entry.get("offset_b", [0.0, 0.0, 0.0]), 3, f"{where}.offset_b", "length")
    frame_b = None
    if entry.get("frame_b", WORLD) != WORLD:
        frame_b = tables.point_frame(entry["frame_b"], pin.SE3(np.eye(3), offset_b), f"{name}/b", f"{where}.frame_b")
    stiffness = tables.quantity(entry.get("stiffness", 0.0), "stiffness", f"{where}.stiffness")
    damping = tables.quantity(entry.get("damping", 0.0), "damping", f"{where}.damping")
    rest = tables.quantity(entry.get("rest_length", 0.0), "length", f"{where}.rest_length")
    for label, value in (("stiffness", stiffness), ("damping", damping), ("rest_length", rest)):
        if value < 0:
            raise SceneError(f"{where}.{label} must be >= 0, got {value}")
    within_ceiling(stiffness, f"{where}.stiffness", "N/m")
    within_ceiling(damping, f"{where}.damping", "N s/m")
    return SpringDamper(name, frame_a, frame_b, offset_b, stiffness, damping, rest)
