"""The interface every constraint family implements (MATH.md section 1)."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from ..kinematics import Kinematics


class Constraint(ABC):
    """A block of constraint rows.

    Holonomic blocks have a residual ``phi(q, t)`` with ``G = d phi / dq`` (right-trivialized on
    the configuration group, i.e. through ``pin.integrate``). Pfaffian blocks only have the velocity
    level ``A(q, t) v + b(q, t) = 0``. Both give the drift term ``gamma0`` of
    ``G a + gamma0 = 0`` (MATH.md eq. 2).

    Attributes:
        name: unique name, used in messages and to slice multipliers.
        rows: number of rows.
        holonomic: whether ``residual`` is defined.
        force_frame: the frame in which this block's multipliers are expressed (human-readable).
    """

    name: str
    rows: int
    holonomic: bool
    force_frame: str

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        """Position-level residual phi [m or rad]; needs placements updated at q."""
        raise NotImplementedError(f"constraint {self.name} is not holonomic")

    @abstractmethod
    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(G, g_t): rows x nv Jacobian and explicit time term; needs Jacobians updated at q."""

    @abstractmethod
    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """gamma0 = dG/dt v + d g_t/dt; needs a full :meth:`Kinematics.update` at (q, v)."""
