"""All constraint blocks of a scene stacked into one set of rows (MATH.md eq. 1-2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConstraintError
from ..kinematics import Kinematics
from .base import Constraint


@dataclass
class ConstraintValues:
    """Stacked constraint quantities at one state (s rows in all).

    Attributes:
        phi: position residual, zero on nonholonomic rows [m or rad].
        jacobian: G, s x nv.
        time_term: g_t (s,).
        velocity_residual: g = G v + g_t [m/s or rad/s].
        drift: gamma0 (s,).
    """

    phi: np.ndarray
    jacobian: np.ndarray
    time_term: np.ndarray
    velocity_residual: np.ndarray
    drift: np.ndarray | None = None


class ConstraintSet:
    """An ordered list of constraint blocks with their row slices."""

    def __init__(self, constraints: list[Constraint], nv: int) -> None:
        names = [c.name for c in constraints]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ConstraintError(f"constraint names must be unique; repeated: {', '.join(duplicates)}")
        self.constraints = list(constraints)
        self.nv = nv
        self.slices: dict[str, slice] = {}
        start = 0
        for c in self.constraints:
            self.slices[c.name] = slice(start, start + c.rows)
            start += c.rows
        self.rows = start
        self.holonomic_mask = np.zeros(self.rows, dtype=bool)
        for c in self.constraints:
            self.holonomic_mask[self.slices[c.name]] = c.holonomic

    @property
    def holonomic(self) -> list[Constraint]:
        return [c for c in self.constraints if c.holonomic]

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        """phi on every row (zero on nonholonomic rows); placements must be current."""
        phi = np.zeros(self.rows)
        for c in self.constraints:
            if c.holonomic:
                phi[self.slices[c.name]] = c.residual(kin, q, t)
        return phi

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(G, g_t); Jacobians must be current."""
        jac = np.zeros((self.rows, self.nv))
        time_term = np.zeros(self.rows)
        for c in self.constraints:
            rows = self.slices[c.name]
            jac[rows], time_term[rows] = c.velocity_terms(kin, q, t)
        return jac, time_term

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """gamma0; needs a full kinematics update at (q, v)."""
        gamma = np.zeros(self.rows)
        for c in self.constraints:
            gamma[self.slices[c.name]] = c.drift(kin, q, v, t)
        return gamma

    def values(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float, with_drift: bool) -> ConstraintValues:
        """Everything at (q, v, t); ``kin`` must have been updated at that state."""
        phi = self.residual(kin, q, t)
        jac, time_term = self.velocity_terms(kin, q, t)
        drift = self.drift(kin, q, v, t) if with_drift else None
        return ConstraintValues(phi, jac, time_term, jac @ v + time_term, drift)
