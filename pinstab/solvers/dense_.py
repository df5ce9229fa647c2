"""``dense``: elimination through the Delassus matrix (the core's direct solve); refuses rank-deficient constraints."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .. import kernels
from ..errors import SolverError
from ..registry import NoOptions
from .base import SOLVERS, KKTProblem, KKTSolution, KKTSolver, check_row_kinds, primal_residual

if TYPE_CHECKING:
    from ..model import ConstrainedModel

RANK_TOLERANCE = 1e-10


class DenseSolver(KKTSolver):
    """``lambda = (G M^-1 G^T)^-1 (rhs - G M^-1 f)``, ``a = M^-1 (f + G^T lambda)``.

    Args:
        row_names: a name per constraint row, for the rank-loss message.
    """

    name = "dense"

    def __init__(self, row_names: list[str] | tuple[str, ...]) -> None:
        super().__init__()
        self.row_names = list(row_names)

    def solve(self, problem: KKTProblem) -> KKTSolution:
        jac = problem.jacobian
        terms = (problem.mass_matrix, problem.free_force, jac, problem.rhs)
        if not all(np.isfinite(term).all() for term in terms):  # a diverging state: the caller says so
            return self.record(KKTSolution(np.full(jac.shape[1], math.nan), np.full(jac.shape[0], math.nan)))
        # the core's direct solve (cpp/kkt_solve.cpp: Cholesky factors of M and D, one refinement step), with this
        # backend's pivot margin
        solved = kernels.direct_solve(*terms, RANK_TOLERANCE)
        if solved is None:
            try:
                np.linalg.cholesky(problem.mass_matrix)
            except np.linalg.LinAlgError:
                raise SolverError(
                    "dense: the joint-space inertia matrix is singular (a massless moving subtree?)"
                ) from None
            eigenvalues, eigenvectors = np.linalg.eigh(jac @ np.linalg.solve(problem.mass_matrix, jac.T))
            raise SolverError(self._rank_message(eigenvalues, eigenvectors))
        acceleration, multipliers = solved
        if jac.shape[0] == 0:
            return self.record(KKTSolution(acceleration, multipliers))
        # the equations of motion hold by construction (a = M^-1 (f + G^T lambda)): only the rows are measured
        primal = primal_residual(problem, acceleration)
        return self.record(KKTSolution(acceleration, multipliers, "solved", 0, primal, math.nan))

    def _rank_message(self, eigenvalues: np.ndarray, eigenvectors: np.ndarray) -> str:
        scale = max(eigenvalues[-1], 1e-300)
        deficient = eigenvalues <= RANK_TOLERANCE * scale
        rank = int(np.sum(~deficient))
        involved = np.abs(eigenvectors[:, deficient]).max(axis=1) > 1e-6
        rows = sorted({self.row_names[i] for i in np.flatnonzero(involved)})
        return (
            f"dense: the constraint Jacobian lost rank ({rank} independent of {len(eigenvalues)} rows); "
            f"dependent rows in: {', '.join(rows)}. The constraints are redundant, or the mechanism is at "
            "a singular configuration, so the multipliers are not unique. Use solver 'proxsuite' (or "
            "'pinocchio'), which handle rank loss."
        )


@SOLVERS.register(
    "dense",
    options=NoOptions,
    summary="numpy elimination through the Delassus matrix (no rank loss)",
    capabilities=DenseSolver.row_kinds,
)
def make_dense(model: ConstrainedModel, corrector_gains: tuple[float, float] | None, options: NoOptions) -> DenseSolver:
    """The dense backend for a model with equality rows only."""
    check_row_kinds(DenseSolver, model)
    return DenseSolver(model.constraints.layout.names)
