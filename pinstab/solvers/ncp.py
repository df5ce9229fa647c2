"""The frictional contact problem on exact round cones, solved by Pinocchio 4.1's ADMM in NCP mode, checked.

Given the Delassus matrix ``D = J M^-1 J^T`` of some contacts and the offset ``g`` (contact velocities or
accelerations without contact forces, plus any bias), find the contact impulses (or forces) ``lambda`` with

    lambda in K,   sigma = D lambda + g,   sigma + mu |sigma_t| e_n in K*,   lambda . sigma = 0

per contact, K the round cone ``|lambda_t| <= mu lambda_n`` (De Saxce's form of Coulomb's law: a sliding
contact's sigma_n is exactly 0 and its friction opposes sigma_t; ``solve_ncp``). The convex relaxation
(CCP, ``solve_ncp = False``) would let sliding contacts lift off by ``mu |sigma_t|``; it is never used here.
Each contact's three rows are in Pinocchio's order (t1, t2, n): normal last.

:meth:`NcpSolver.solve_contacts` does not take a solver's word for it (its rules, below, are compiled:
``pinstab._compiled.ConeSolver``, cpp/cone_solve.hpp, which the compiled time-stepping step calls too). It poses the
problem with each contact's tangential impulse in units of ``s = max(mu, 1)`` times the normal one (``lambda = S
lambda'``, ``D' = S D S``, ``g' = S g``, cones of ``mu / s <= 1``: the same problem, ``lambda' . sigma' = lambda .
sigma`` and ``sigma'_n + (mu / s) |sigma'_t| = sigma_n + mu |sigma_t|``), because ADMM in NCP mode fails on steep
cones: on the painleve-rod it missed the first step at mu = 4 and 5 (0.9 and 1.3 m/s off the law on a 1 m/s slip)
and returned NaN 0.8 s on at mu = 10, where the scaled problems converge in 40 to 200 iterations. Cones below 1 are
left as they are (scaling them up would shrink the tangential block of D by mu^2). Each answer is then measured by
:func:`ncp_residual`, the natural map of the De Saxce law computed there, and kept only within :data:`CHECK_RTOL`,
whatever the solver's own flag says (checked after runs of :data:`CHECK_EVERY` iterations, half as many, twice as many
and so on: a passing answer ends the solve once the residual settles, :data:`ROUND_SETTLED`); else Pinocchio's projected
Gauss-Seidel in NCP mode (PGS) solves the same problem, checked the same way, and if it misses too the solve reports
that it did not converge (the callers stop the run with a :class:`~pinstab.errors.ContactSolveError` or
:class:`~pinstab.errors.ContactInfeasibleError`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from ..kernels import ConeSolver
from ..kernels import ncp_residual as compiled_residual
from ..runinfo import SolverStatistics

CHECK_RTOL = 1e-6
"""[-] the largest residual :func:`ncp_residual` accepts, relative to the problem's velocity scale (the largest
entry of g or of D lambda): a contact velocity off the law by less moves a contact by 1e-6 of its free travel
per step (1 nm per 1 ms step at 1 m/s). It lies 400 times above the worst residual of ADMM's converged
answers (tolerance 1e-12) over the bundled contact scenes at mu in [0, 10] (2.4e-9, allegro-tilt) and far below
the misses it must catch (ADMM on the painleve-rod at mu = 4: 0.9 of the 1 m/s slip; 1.4e-2 at mu = 7)."""
LANCZOS_SIZE = 12
"""[-] the Lanczos steps of ADMM's estimate of D's largest eigenvalue (its spectral rho rule). Pinocchio's default
takes one per row: on box-stack's 12 sticking corners (36 rows) that estimate was 3/4 of the solve (229 us; 58 us
with 12 steps, the same 26 iterations to the same tolerance)."""
CHECK_EVERY = 128
"""[-] the iterations of the first run of ADMM (and of PGS): the solve runs from zero for 128 iterations, then 64 (the
first run's answer half-way), then 256, 512 and so on up to the iteration limit (each run the first iterations of the
longest: the answers a single run passes through; restarts from the last answer lost the lever scene's ill-conditioned
problem), its answer checked by :func:`ncp_residual` after each run, and ends once the residual settles
(:data:`ROUND_SETTLED`) or the solver meets its own tolerance. The half run tells a residual settled within the first
run (redundant contacts: hand-cube's median unconverged solve passes the check at 1e-5 of it after 32 iterations and
stays there) without a run of 256 (386 iterations -> 194). The first run holds the converged solves of box-stack,
incline and sphere-spin (26, 63 and 123 iterations at most: unchanged; runs from 50 doubled those of the last two). On
redundant contacts (a rank-deficient D: hand-cube's cube between the palm, three fingertips and the table, 11 contacts,
33 rows of rank 12) the impulses are not unique and ADMM's iterates drift within the set of solutions (the change of
lambda, which its own tolerances bound, stays near 1e-8 while the contact velocities have settled to 1e-9 of their
scale): run to its own tolerance it went on to 1e5 iterations, and its answer after 1e4 could miss the check
(hand-cube's set-down with the admission growth of :mod:`~pinstab.integration.contact_stepping`;
tests/test_ncp_redundant.py). So run, hand-cube's solves (dt = 1 ms, 2,200) take 39 iterations on average, 451 at most
(60 and 899 without the half run), every answer ADMM's."""
ROUND_SETTLED = 0.5
"""[-] a run that shrinks the residual by less than this factor against the run of half its iterations, once an
answer has passed the check, ends the solve (the best answer kept): the residual has settled (redundant contacts),
where a converging solve (the painleve-rod's steep cones, 40 to 200 iterations) goes on to its own tolerance."""
CONE_ROWS = (1, 2, 0)  # Pinocchio's rows (t1, t2, n) as indices of pinstab's (n, t1, t2)
CONE_ORDER = np.eye(3)[list(CONE_ROWS)]  # (n, t1, t2) -> (t1, t2, n)


def admm_settings(tolerance: float, max_iterations: int) -> pin.ADMMSolverSettings:
    """ADMM's settings in NCP mode with every feasibility and complementarity tolerance (absolute and
    relative) at ``tolerance`` and the spectral rho rule of Pinocchio's example (:data:`LANCZOS_SIZE` steps)."""
    settings = pin.ADMMSolverSettings()
    settings.max_iterations = max_iterations
    settings.solve_ncp = True
    for name in ("feasibility", "complementarity"):
        setattr(settings, f"absolute_{name}_tol", tolerance)
        setattr(settings, f"relative_{name}_tol", tolerance)
    settings.admm_update_rule = pin.ADMMUpdateRule.SPECTRAL
    settings.lanczos_size = LANCZOS_SIZE
    return settings


class NcpStatus(NamedTuple):
    """How the last solve ended: the solver's iterations, convergence flag (for :meth:`NcpSolver.solve_contacts`:
    the answer kept passed :func:`ncp_residual`) and final primal and dual feasibility and complementarity
    residuals (in the units of g; complementarity times lambda's)."""

    iterations: int
    converged: bool
    primal_feasibility: float
    dual_feasibility: float
    complementarity: float


class NcpSolver:
    """Pinocchio's ``ADMMConstraintSolver`` on a dense Delassus matrix, in NCP mode, with a checked fallback.

    Args:
        size: the largest problem size (3 per contact).
        tolerance: ADMM's and PGS's absolute and relative feasibility and complementarity tolerances.
        max_iterations: ADMM's and PGS's iteration limit.
        compliance: the compliance R added to D's diagonal (units of g per unit of lambda), 0 for rigid
            contacts (used by :meth:`solve` alone).
        warm_start: start each :meth:`solve` from the previous one's lambda (when the sizes match).

    Attributes:
        size: the largest problem size it takes (at least 3). result: Pinocchio's ``ADMMSolverResult`` of the last
        :meth:`solve`. cones: the compiled checked solve (``pinstab._compiled.ConeSolver``) of :meth:`solve_contacts`,
        which the compiled time-stepping step calls too. method: the solver whose answer the last
            :meth:`solve_contacts` kept (``ADMM`` or ``PGS``; the last one tried when none passed). residual:
            that answer's :func:`ncp_residual` [units of g]. tolerance: the residual it accepted [units of g].
    """

    def __init__(
        self,
        size: int,
        tolerance: float = 1e-12,
        max_iterations: int = 10_000,
        compliance: float = 0.0,
        warm_start: bool = False,
    ) -> None:
        size = max(size, 3)
        self.size = size
        self.settings = admm_settings(tolerance, max_iterations)
        self.solver = pin.ADMMConstraintSolver(size)
        self.result = pin.ADMMSolverResult()
        self.cones = ConeSolver(size, tolerance, max_iterations, LANCZOS_SIZE, CHECK_EVERY, ROUND_SETTLED)
        self.compliance = compliance
        self.warm_start = warm_start
        self.method, self.residual, self.tolerance = "ADMM", 0.0, 0.0
        self._last_size = -1
        self._status = NcpStatus(0, False, math.nan, math.nan, math.nan)

    def solve(self, delassus: np.ndarray, g: np.ndarray, models, datas) -> np.ndarray:
        """ADMM's lambda of the problem ``(D, g)`` on the cones of the constraint ``models`` (their friction
        coefficients; ``datas`` their data), in Pinocchio's row order (t1, t2, n per contact), unchecked."""
        operator = pin.DelassusOperatorDense(0.5 * (delassus + delassus.T))
        if self.compliance:
            operator.updateCompliance(self.compliance)
        result = self.result
        if self.warm_start and result.isValid() and self._last_size == g.size:
            result.setConstraintImpulseGuess(result.retrieveConstraintImpulses().copy())
        self.solver.solve(operator, g, models, datas, self.settings, result)
        self._last_size = g.size
        self.method, self._status = "ADMM", _status_of(result)
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
        active rows (converted to Pinocchio's order for the solve). ADMM on the problem with the cones scaled to
        at most 1, then PGS when ADMM's answer misses :func:`ncp_residual`'s tolerance; :meth:`status` says
        whether the answer returned passed it."""
        rows = np.array([3 * i + r for i in active for r in CONE_ROWS])
        delassus, g = jacobian[rows] @ mobility[:, rows], offset[rows]
        solution = self.cones.solve(delassus, g, np.asarray(mus, dtype=float), CHECK_RTOL)
        self.read_status()
        return solution.reshape(-1, 3)[:, np.argsort(CONE_ROWS)]

    def read_status(self) -> None:
        """Take the last checked solve's status from the compiled solver (:attr:`cones`): the solver kept, its
        residual, the residual accepted, the status."""
        method, iterations, converged, primal, dual, complementarity, residual, accepted = self.cones.status
        self.method, self.residual, self.tolerance = method, residual, accepted
        self._status = NcpStatus(iterations, converged, primal, dual, complementarity)

    def record(self, statistics: SolverStatistics) -> None:
        """Count the last solve in ``statistics`` (status ``ADMM converged``, ``PGS converged`` or ``ADMM, PGS
        not converged``, the kept solver's iterations and absolute primal and dual residuals; a PGS solve after
        ADMM's miss is a fallback)."""
        status = self.status()
        missed = "ADMM-torsion not converged" if self.method == "ADMM-torsion" else "ADMM, PGS not converged"
        label = f"{self.method} converged" if status.converged else missed
        statistics.record(label, status.iterations, status.primal_feasibility, status.dual_feasibility)
        statistics.fallbacks += self.method == "PGS"

    def status(self) -> NcpStatus:
        """How the last solve ended."""
        return self._status

    def failure(self) -> str:
        """Why the last :meth:`solve_contacts` returned an answer that misses the contact law (for an error's
        message): the solvers tried, their iteration limit, the residual and the tolerance [m/s or N s units of g]."""
        limit = f"(NCP mode, {self.settings.max_iterations} iterations)"
        missed = (
            f"the torsion ADMM {limit} did not meet the contact law"
            if self.method == "ADMM-torsion"
            else f"neither ADMM nor PGS {limit} met the contact law"
        )
        return f"{missed} (residual {self.residual:.3g}, accepted {self.tolerance:.3g})"


def _status_of(result) -> NcpStatus:
    """The status of an ADMM or PGS ``result``."""
    return NcpStatus(
        int(result.iterations),
        bool(result.converged),
        float(result.primal_feasibility),
        float(result.dual_feasibility),
        float(result.complementarity),
    )


def ncp_residual(
    delassus: np.ndarray,
    g: np.ndarray,
    impulses: np.ndarray,
    mus: Sequence[float],
    torsions: Sequence[float] | None = None,
) -> float:
    """How far ``impulses`` (Pinocchio's order, t1, t2, n per contact) are from solving the problem ``(D, g)``
    with friction coefficients ``mus`` [-], in the units of g: the largest contact's natural map
    ``|lambda - P_K(lambda - rho (sigma + mu |sigma_t| e_n))| / rho``, ``rho = 1 / trace D`` (at most
    ``1 / |D|_2``: the map over rho only grows as rho shrinks); 0 exactly at a solution (lambda in K, sigma_n >= 0,
    lambda orthogonal to the De Saxce velocity), inf for a non-finite lambda (compiled: the check of
    :meth:`NcpSolver.solve_contacts` computes it there). With ``torsions`` (torsion lengths [m], one per contact),
    the problem has one more row per torsion > 0 after the contacts' (cpp/torsion_cone.hpp): K bounds its torque by
    torsion lambda_n too, and the De Saxce velocity adds torsion |sigma_tau|."""
    arrays = [np.asarray(x, dtype=float) for x in (delassus, g, impulses, mus)]
    return compiled_residual(*arrays, None if torsions is None else np.asarray(torsions, dtype=float))


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
