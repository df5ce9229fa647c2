"""``extended``: a reference solve, the KKT system taken whole by least squares with residuals in extended precision.

    [[M, -G^T], [G, 0]] [a; lambda] = [f; rhs]

is solved by LAPACK's least squares (``numpy.linalg.lstsq``), then refined :data:`REFINEMENTS` times with residuals
summed in ``long double``. It forms no Delassus matrix G M^-1 G^T (whose condition number is the rows' squared), so near
a singular configuration it stays at the rounding of the system itself: a reference for the other backends, not a
fast one. Redundant rows get the least-norm multipliers.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..registry import NoOptions
from .base import SOLVERS, KKTProblem, KKTSolution, KKTSolver, check_row_kinds, primal_residual

if TYPE_CHECKING:
    from ..model import ConstrainedModel

REFINEMENTS = 4  # refinement steps after the first solve (on delta's singular passage the second changes nothing)


class ExtendedSolver(KKTSolver):
    """The equality KKT system solved whole, refined in extended precision (see the module)."""

    name = "extended"

    def solve(self, problem: KKTProblem) -> KKTSolution:
        nv, s = problem.mass_matrix.shape[0], problem.jacobian.shape[0]
        system = np.block([[problem.mass_matrix, -problem.jacobian.T], [problem.jacobian, np.zeros((s, s))]])
        target = np.concatenate([problem.free_force, problem.rhs]).astype(np.longdouble)
        wide = system.astype(np.longdouble)
        solution = np.zeros(nv + s, dtype=np.longdouble)
        try:
            for _ in range(1 + REFINEMENTS):
                miss = np.asarray(target - wide @ solution, dtype=float)
                solution = solution + np.linalg.lstsq(system, miss, rcond=None)[0]
        except np.linalg.LinAlgError:  # a non-finite system: the caller reports the non-finite acceleration
            return self.record(KKTSolution(np.full(nv, math.nan), np.full(s, math.nan), "failed"))
        result = np.asarray(solution, dtype=float)
        acceleration = result[:nv]
        return self.record(
            KKTSolution(acceleration, result[nv:], "solved", 1 + REFINEMENTS, primal_residual(problem, acceleration))
        )


@SOLVERS.register(
    "extended",
    options=NoOptions,
    summary="reference: the whole KKT system by least squares refined in extended precision (slow)",
    capabilities=ExtendedSolver.row_kinds,
)
def make_extended(
    model: ConstrainedModel, corrector_gains: tuple[float, float] | None, options: NoOptions
) -> ExtendedSolver:
    """The extended-precision reference backend for a model with equality rows only."""
    check_row_kinds(ExtendedSolver, model)
    return ExtendedSolver()
