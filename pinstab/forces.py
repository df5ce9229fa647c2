"""Force elements: joint torques (constant or a time table) and linear spring-dampers."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from .kinematics import Kinematics


class ForceElement(ABC):
    """Something that adds a generalized force and possibly potential energy."""

    name: str

    @abstractmethod
    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        """Generalized force [N, N m] (nv,); needs placements and Jacobians current."""

    def potential_energy(self, kin: Kinematics) -> float:
        """Stored energy [J]; zero for non-conservative elements."""
        return 0.0


class JointTorque(ForceElement):
    """A torque (revolute) or force (prismatic) on one joint DOF.

    Args:
        name: element name.
        dof: index of the joint's velocity coordinate.
        times: table times [s], increasing (a single entry for a constant).
        values: table values [N m or N]; linear interpolation, held at the ends.
    """

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

    def potential_energy(self, kin: Kinematics) -> float:
        _, length, _ = self._geometry(kin)
        return 0.5 * self.stiffness * (length - self.rest_length) ** 2
