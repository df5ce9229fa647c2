"""The constrained-dynamics problem handed to a KKT backend, and what comes back (MATH.md eq. 4-5)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np


@dataclass
class KKTProblem:
    """``M a = f + G^T lambda``, ``G a = rhs``.

    Attributes:
        q, v: state (some backends recompute the dynamics themselves).
        tau: applied generalized forces (force elements) [N, N m].
        mass_matrix: M [kg, kg m^2].
        free_force: f = tau - h [N, N m].
        jacobian: G (s x nv).
        rhs: -gamma0 + gamma_stab [m/s^2, rad/s^2].
    """

    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    mass_matrix: np.ndarray
    free_force: np.ndarray
    jacobian: np.ndarray
    rhs: np.ndarray


@dataclass
class KKTSolution:
    """Accelerations [m/s^2, rad/s^2] (nv,) and multipliers (s,) [N, N m]."""

    acceleration: np.ndarray
    multipliers: np.ndarray


class KKTSolver(ABC):
    """A backend that solves :class:`KKTProblem`.

    Attributes:
        fallbacks: how many solves were handed to a rank-robust backend after this one missed
            the acceleration-level constraint (only backends with a fallback count them).
    """

    name: str
    fallbacks: int = 0

    @abstractmethod
    def solve(self, problem: KKTProblem) -> KKTSolution:
        """Solve one KKT system; raise :class:`~pinstab.errors.SolverError` on failure."""
