"""``proxsuite``: Gauss's principle as an equality QP solved by ProxQP, warm-started.

``min_a 1/2 a^T M a - f^T a  s.t.  G a = rhs`` (MATH.md eq. 5). The proximal method keeps the
problem well-posed when G is rank-deficient (redundant or singular rows): the accelerations stay
unique, the multipliers are the minimum-norm ones the proximal iterations converge to.
"""

from __future__ import annotations

import numpy as np
import proxsuite

from ..errors import SolverError
from .base import KKTProblem, KKTSolution, KKTSolver

NEARLY = 1e-7  # relative residual accepted when ProxQP stops on its iteration limit

SOLVED = (
    proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED,
    proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE,
)


class ProxsuiteSolver(KKTSolver):
    """ProxQP dense backend.

    Args:
        eps_abs: absolute accuracy of the primal and dual residuals.
    """

    name = "proxsuite"

    def __init__(self, eps_abs: float = 1e-12) -> None:
        self.eps_abs = eps_abs
        self._qp: proxsuite.proxqp.dense.QP | None = None

    def _fresh(self, nv: int, rows: int) -> proxsuite.proxqp.dense.QP:
        qp = proxsuite.proxqp.dense.QP(nv, rows, 0)
        qp.settings.eps_abs = self.eps_abs
        qp.settings.eps_rel = self.eps_abs
        qp.settings.verbose = False
        qp.settings.max_iter = 1000
        # at a singular configuration -gamma0 can leave range(G) by rounding: take the closest
        # feasible accelerations (least-squares constraint rows) instead of declaring infeasibility
        qp.settings.primal_infeasibility_solving = True
        return qp

    def solve(self, problem: KKTProblem) -> KKTSolution:
        nv, rows = problem.mass_matrix.shape[0], problem.jacobian.shape[0]
        neg_f = -problem.free_force
        if self._qp is None or self._qp.model.dim != nv or self._qp.model.n_eq != rows:
            self._qp = self._fresh(nv, rows)
            self._qp.init(problem.mass_matrix, neg_f, problem.jacobian, problem.rhs, None, None, None)
        else:
            self._qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            self._qp.update(problem.mass_matrix, neg_f, problem.jacobian, problem.rhs, None, None, None)
        self._qp.solve()
        if self._qp.results.info.status not in SOLVED:
            # a warm start far from the answer (a state changing fast) can stall: retry cold
            self._qp = self._fresh(nv, rows)
            self._qp.init(problem.mass_matrix, neg_f, problem.jacobian, problem.rhs, None, None, None)
            self._qp.solve()
        results = self._qp.results
        status = results.info.status
        if status not in SOLVED and not self._nearly_solved(problem):
            raise SolverError(
                f"proxsuite: ProxQP did not solve the constrained dynamics ({status.name}, primal residual "
                f"{results.info.pri_res:.3g}, dual residual {results.info.dua_res:.3g}). Either the constraints are "
                "inconsistent (conflicting closures, not merely redundant) or the run is blowing up (reduce dt or "
                "the gains)"
            )
        return KKTSolution(np.array(results.x), -np.array(results.y))

    def _nearly_solved(self, problem: KKTProblem) -> bool:
        """Next to a singular configuration ProxQP may stop on its iteration limit a little above
        eps_abs; accept the answer when the constraint rows still hold to NEARLY relative."""
        info = self._qp.results.info
        if info.status != proxsuite.proxqp.QPSolverOutput.PROXQP_MAX_ITER_REACHED:
            return False
        scale = 1.0 + float(np.abs(problem.rhs).max(initial=0.0))
        return info.pri_res <= NEARLY * scale and info.dua_res <= NEARLY * (
            1.0 + float(np.abs(problem.free_force).max())
        )
