"""The frictional contact problem on exact round cones, solved by Pinocchio 4.1's ADMM in NCP mode.

Given the Delassus matrix ``D = J M^-1 J^T`` of some contacts and the offset ``g`` (contact velocities or
accelerations without contact forces, plus any bias), find the contact impulses (or forces) ``lambda`` with

    lambda in K,   sigma = D lambda + g,   sigma + mu |sigma_t| e_n in K*,   lambda . sigma = 0

per contact, K the round cone ``|lambda_t| <= mu lambda_n`` (De Saxce's form of Coulomb's law: a sliding
contact's sigma_n is exactly 0 and its friction opposes sigma_t; ``solve_ncp``). The convex relaxation
(CCP, ``solve_ncp = False``) would let sliding contacts lift off by ``mu |sigma_t|``; it is never used here.
Each contact's three rows are in Pinocchio's order (t1, t2, n): normal last.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from ..runinfo import SolverStatistics

CONE_ROWS = (1, 2, 0)  # Pinocchio's rows (t1, t2, n) as indices of pinstab's (n, t1, t2)
CONE_ORDER = np.eye(3)[list(CONE_ROWS)]  # (n, t1, t2) -> (t1, t2, n)


def admm_settings(tolerance: float, max_iterations: int) -> pin.ADMMSolverSettings:
    """ADMM's settings in NCP mode with every feasibility and complementarity tolerance (absolute and
    relative) at ``tolerance`` and the spectral rho rule of Pinocchio's example."""
    settings = pin.ADMMSolverSettings()
    settings.max_iterations = max_iterations
    settings.solve_ncp = True
    for name in ("feasibility", "complementarity"):
        setattr(settings, f"absolute_{name}_tol", tolerance)
        setattr(settings, f"relative_{name}_tol", tolerance)
    settings.admm_update_rule = pin.ADMMUpdateRule.SPECTRAL
    return settings


class NcpStatus(NamedTuple):
    """How the last solve ended: ADMM's iterations, convergence flag and final primal and dual
    feasibility and complementarity residuals (in the units of g; complementarity times lambda's)."""

    iterations: int
    converged: bool
    primal_feasibility: float
    dual_feasibility: float
    complementarity: float


class NcpSolver:
    """Pinocchio's ``ADMMConstraintSolver`` on a dense Delassus matrix, in NCP mode.

    Args:
        size: the largest problem size (3 per contact).
        tolerance: ADMM's absolute and relative feasibility and complementarity tolerances.
        max_iterations: ADMM's iteration limit.
        compliance: the compliance R added to D's diagonal (units of g per unit of lambda), 0 for rigid
            contacts.
        warm_start: start each solve from the previous one's lambda (when the sizes match).

    Attributes:
        result: Pinocchio's ``ADMMSolverResult`` of the last solve.
    """

    def __init__(
        self,
        size: int,
        tolerance: float = 1e-12,
        max_iterations: int = 10_000,
        compliance: float = 0.0,
        warm_start: bool = False,
    ) -> None:
        self.settings = admm_settings(tolerance, max_iterations)
        self.solver = pin.ADMMConstraintSolver(max(size, 3))
        self.result = pin.ADMMSolverResult()
        self.compliance = compliance
        self.warm_start = warm_start
        self._last_size = -1
        self._cones: dict[tuple[float, ...], tuple] = {}

    def solve(self, delassus: np.ndarray, g: np.ndarray, models, datas) -> np.ndarray:
        """lambda of the problem ``(D, g)`` on the cones of the constraint ``models`` (their friction
        coefficients; ``datas`` their data), in Pinocchio's row order (t1, t2, n per contact)."""
        operator = pin.DelassusOperatorDense(0.5 * (delassus + delassus.T))
        if self.compliance:
            operator.updateCompliance(self.compliance)
        result = self.result
        if self.warm_start and result.isValid() and self._last_size == g.size:
            result.setConstraintImpulseGuess(result.retrieveConstraintImpulses().copy())
        self.solver.solve(operator, g, models, datas, self.settings, result)
        self._last_size = g.size
        return result.retrieveConstraintImpulses().copy()

    def solve_contacts(
        self,
        jacobian: np.ndarray,
        mobility: np.ndarray,
        offset: np.ndarray,
        active: Sequence[int],
        mus: Sequence[float],
    ) -> np.ndarray:
        """The impulses (or forces) (len(active), 3) in the contact bases (n, t1, t2) of the contacts
        ``active`` with friction coefficients ``mus`` [-]: ``jacobian`` (3k, nv) and ``offset`` (3k,) [units of
        g] have each contact's rows (n, t1, t2), ``mobility`` (nv, 3k) is M^-1 J^T; D = J M^-1 J^T of the
        active rows (converted to Pinocchio's order for the solve)."""
        rows = np.array([3 * i + r for i in active for r in CONE_ROWS])
        key = tuple(float(mu) for mu in mus)
        if key not in self._cones:
            self._cones[key] = friction_cones(key)
        solution = self.solve(jacobian[rows] @ mobility[:, rows], offset[rows], *self._cones[key])
        return solution.reshape(-1, 3)[:, np.argsort(CONE_ROWS)]

    def record(self, statistics: SolverStatistics) -> None:
        """Count the last solve in ``statistics`` (status ``ADMM converged`` or ``ADMM not converged``, its
        iterations and absolute primal and dual residuals)."""
        status = self.status()
        statistics.record(
            "ADMM converged" if status.converged else "ADMM not converged",
            status.iterations,
            status.primal_feasibility,
            status.dual_feasibility,
        )

    def status(self) -> NcpStatus:
        """How the last solve ended."""
        result = self.result
        return NcpStatus(
            int(result.iterations),
            bool(result.converged),
            float(result.primal_feasibility),
            float(result.dual_feasibility),
            float(result.complementarity),
        )


def friction_cones(mus: Sequence[float]) -> tuple[pin.StdVec_ConstraintModel, pin.StdVec_ConstraintData]:
    """Constraint models that carry only the round cones ``|lambda_t| <= mu lambda_n`` of friction
    coefficients ``mus`` [-] (what :meth:`NcpSolver.solve` reads of them), with their data."""
    empty = pin.Model()
    models, datas = pin.StdVec_ConstraintModel(), pin.StdVec_ConstraintData()
    for mu in mus:
        cone = pin.PointContactConstraintModel(empty, 0, pin.SE3.Identity(), 0, pin.SE3.Identity())
        cone.setFriction(float(mu))
        models.append(cone)
        datas.append(models[len(models) - 1].createData())
    return models, datas
