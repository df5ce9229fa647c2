"""Coulomb friction cones and their linearization (inscribed pyramids) for solvers without conic support."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import ConstraintError

MAX_CONE_FACETS = 1000  # sides of a linearized friction cone in the dynamics (contacts, grasp control): more
# only costs time


@dataclass(frozen=True)
class FrictionCone:
    """A Coulomb friction cone and its linearization.

    Attributes:
        mu: friction coefficient [-]. facets: sides of the inscribed pyramid a solver without conic
        support uses (every force inside the pyramid is inside the cone).
    """

    mu: float
    facets: int = 8

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mu) and self.mu >= 0):
            raise ConstraintError(f"friction coefficient mu must be a finite number >= 0, got {self.mu}")
        if isinstance(self.facets, bool) or not isinstance(self.facets, int) or not 3 <= self.facets <= MAX_CONE_FACETS:
            raise ConstraintError(
                f"a linearized friction cone needs at least 3 facets (at most {MAX_CONE_FACETS}), got {self.facets!r}"
            )

    @property
    def inscribed_mu(self) -> float:
        """The friction coefficient of the inscribed pyramid: mu cos(pi / facets)."""
        return self.mu * math.cos(math.pi / self.facets)

    @cached_property
    def facet_matrix(self) -> np.ndarray:
        """``facets x 3`` rows c with ``c . (f_n, f_t1, f_t2) <= 0`` the pyramid's facets."""
        angles = 2.0 * math.pi * np.arange(self.facets) / self.facets
        return np.column_stack([-np.full(self.facets, self.inscribed_mu), np.cos(angles), np.sin(angles)])
