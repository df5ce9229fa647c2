"""``dense``: numpy elimination through the Delassus matrix; refuses rank-deficient constraints."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

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
        try:
            solved = np.linalg.solve(problem.mass_matrix, np.column_stack([problem.free_force, jac.T]))
        except np.linalg.LinAlgError:
            raise SolverError(
                "dense: the joint-space inertia matrix is singular (a massless moving subtree?)"
            ) from None
        free_acceleration, minv_gt = solved[:, 0], solved[:, 1:]
        if jac.shape[0] == 0:
            return self.record(KKTSolution(free_acceleration, np.zeros(0)))
        delassus = jac @ minv_gt
        # Cholesky of the Delassus matrix: it fails, or leaves a tiny pivot, exactly when G loses rank
        try:
            factor = np.linalg.cholesky(delassus)
            pivots = np.diagonal(factor) ** 2
            deficient = pivots.min() <= RANK_TOLERANCE * max(float(np.diagonal(delassus).max()), 1e-300)
        except np.linalg.LinAlgError:
            deficient = True
        if deficient:
            eigenvalues, eigenvectors = np.linalg.eigh(delassus)
            raise SolverError(self._rank_message(eigenvalues, eigenvectors))
        multipliers = np.linalg.solve(delassus, problem.rhs - jac @ free_acceleration)
        acceleration = free_acceleration + minv_gt @ multipliers
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
