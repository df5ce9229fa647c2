"""``spring-damper``: a linear spring-damper between two frame points (or a frame point and a world point)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import SceneError
from ..kernels import SPRING_COINCIDENT_LENGTH, spring_damper_terms
from ..kinematics import Kinematics
from ..tables import WORLD, SceneTables
from ..units import within_ceiling
from .base import FORCE_KINDS, ForceElement

SPRING_KEYS = {"name", "kind", "frame_a", "offset_a", "frame_b", "offset_b", "stiffness", "damping", "rest_length"}


class SpringDamper(ForceElement):
    """A linear spring-damper between two frame points (``frame_b`` None: a fixed world point), computed by the
    compiled core's law (``cpp/spring_damper.cpp``, which its core kernel runs too).

    Force on point a: ``-(k (L - L0) + c dL/dt) u`` with ``u = (p_a - p_b)/L``, on point b its opposite: the
    generalized force ``(J_a - J_b)^T F``. Where the points coincide (L < 1e-12 m) u is not defined: a zero-rest-length
    spring without damping keeps its force ``-k (p_a - p_b)`` there, any other refuses the state (SceneError).

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
        self._form = self.compiled_form({})

    def compiled_form(self, rows: Mapping[str, slice]) -> dict[str, Any]:
        """The element as the core kernel takes it (``cpp/spring_damper.hpp`` SpringDamperSpec)."""
        return {
            "kind": "spring-damper",
            "frame_a": int(self.frame_a),
            "frame_b": -1 if self.frame_b is None else int(self.frame_b),
            "point_b": self.world_point_b,
            "stiffness": float(self.stiffness),
            "damping": float(self.damping),
            "rest_length": float(self.rest_length),
        }

    def terms(self, kin: Kinematics, v: np.ndarray) -> tuple[float, float, np.ndarray]:
        """The length L [m], its rate dL/dt [m/s] and the generalized force [N, N m] (nv,) at (kin's q, v).

        Raises:
            SceneError: the points coincide and the law needs the direction between them.
        """
        length, rate, force = spring_damper_terms(kin.model, kin.data, self._form, v)
        if force is None:
            raise SceneError(
                f"spring-damper {self.name!r}: its points coincide (length {length:.3g} m < "
                f"{SPRING_COINCIDENT_LENGTH:g} m), where the direction of its force (rest length {self.rest_length:g} "
                f"m, damping {self.damping:g} N s/m) is not defined; keep the points apart, or give rest_length = 0 "
                "and damping = 0 (then -k (p_a - p_b))"
            )
        return length, rate, force

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        return self.terms(kin, v)[2]

    def power(self, kin: Kinematics, v: np.ndarray, t: float) -> float:
        return -self.damping * self.terms(kin, v)[1] ** 2

    @property
    def stores_energy(self) -> bool:
        return self.stiffness != 0.0

    def potential_energy(self, kin: Kinematics) -> float:
        """``k (L - L0)^2 / 2`` [J], the potential of the law's spring part (L from the same compiled line)."""
        length = spring_damper_terms(kin.model, kin.data, self._form, np.zeros(kin.model.nv))[0]
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
