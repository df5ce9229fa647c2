"""``proxsuite``: Gauss's principle as a QP solved by ProxQP, scaled, warm-started, judged by residuals.

Equality rows only (closures, user rows): ``min_a 1/2 a^T M a - f^T a  s.t.  G a = rhs`` (docs/mathematics.md
eq. 5). The proximal method keeps the problem well-posed when G is rank-deficient (redundant or
singular rows): the accelerations stay unique, the multipliers are the minimum-norm ones.

With unilateral or cone rows the variables are the accelerations and the multipliers together,
``x = (a, lambda)``: the same objective plus a tiny ``eps/2 |lambda|^2`` that picks the smallest of
equivalent force distributions (a statically indeterminate grasp; polished afterwards to the exact
minimum-norm forces when those keep every cone, else to the smallest inside the cones), subject to
``M a - G^T lambda = f``, ``G a = rhs`` on equality and cone rows, ``G a >= rhs`` and ``lambda >= 0`` on
unilateral rows, and the inscribed pyramid of each friction cone (``facets`` sides, so every answer is inside the exact
cone). When ProxQP's answer is not accepted, a linear program (HiGHS, exact and deterministic) decides whether the
contacts can hold: a sticking contact that would need a force outside its cone is reported as
:class:`~pinstab.errors.ContactInfeasibleError`, naming the contact. Contacts that can hold, and any answer ProxQP did
not finish (forces pinned against a cone), are solved again with a larger regularization
(:data:`RETRY_REGULARIZATION`); the unfinished answer is kept only when the retry's is not accepted.
ProxQP's work per solve is bounded (``max_iter`` outer iterations of at most :data:`MAX_ITER_IN` inner ones).

Scaling: ProxQP's tolerances and infeasibility thresholds are absolute, so the problem is scaled
before it is handed over: accelerations by the square root of M's diagonal (relative to its mean),
the objective by that mean, each constraint row by its norm. The scaled problem is the same for a
mechanism in millimetres and grams as in metres and kilograms. A solve is accepted by its residuals:
ProxQP's own when it reports them within its tolerance (relative ones on the scaled problem), and
otherwise pinstab's, recomputed on the unscaled problem and accepted below
:data:`~pinstab.solvers.base.ACCEPTED_RESIDUAL` (relative) whatever flag ProxQP raised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import linprog

from .. import kernels
from ..constraints import ConeRows, RowKind
from ..errors import ContactInfeasibleError, SolverError
from ..proxqp import proxsuite
from .base import ACCEPTED_RESIDUAL, SOLVERS, KKTProblem, KKTSolution, KKTSolver, primal_residual, residuals

if TYPE_CHECKING:
    from ..model import ConstrainedModel

FORCE_REGULARIZATION = 1e-9  # eps of the (a, lambda) form, in scaled units
# eps of the retry when ProxQP did not finish with FORCE_REGULARIZATION on contacts that can hold (a linear program says
# so when the answer is not accepted):
# forces pinned against a cone make the problem nearly a linear program, which the proximal method then does not
# finish (1,000 outer iterations) or even declares infeasible. The retry trades accelerations for smaller forces by
# at most this relative to the scaled terms (of order one): 1e-6, below the integrators' step errors at the steps
# held contacts take, and enough to solve the clamped box (box-push with a corner under a ceiling) in ~20 iterations
RETRY_REGULARIZATION = 1e-6
RESCALE_EVERY = 64  # solves between refreshes of the scaling (it follows the configuration slowly)
CONE_TOLERANCE = 1e-8  # a facet or sign may be missed by this much relative to the forces in play
DIRECT_PIVOT = 1e-8  # the Delassus matrix's smallest Cholesky pivot over its largest diagonal entry, at least
DIRECT_STATUS = "cholesky"  # the status of a direct solve (equality rows independent by a margin)
# a row whose largest (column-scaled) entry is below this fraction of the largest row's is rounding of a row that is
# zero at this configuration (a redundant closure's rotation rows, or its translation row across both slides, come out
# at 1e-16 of the others): scaled by its own size it would become a unit row of noise, with a right-hand side of
# rounding over rounding (-2.3e-15 / 1.5e-16 = -16), and ProxQP finds the rows inconsistent (PRIMAL_INFEASIBLE) or
# not, by the rounding of each solve; it keeps the largest row's scale instead. A genuine row that small would need
# lever arms 1e-12 of the mechanism's size.
ROUNDING_ROW = 1e-12
# inner iterations per outer iteration of ProxQP (its default 1500): a contact problem whose forces are statically
# indeterminate and pinned against a cone (a corner clamped between a ceiling and the floor) never meets eps_abs, and
# each outer iteration's inner solve then ran to ~700 (a cold solve: 700,000 inner iterations, 3.5 s); the answer is
# judged by its residuals either way, so the work per solve is bounded by max_iter times this
MAX_ITER_IN = 50


@dataclass(frozen=True)
class ProxsuiteOptions:
    """Options of the ``proxsuite`` backend."""

    eps_abs: float = field(
        default=1e-12, metadata={"flag": "--proxsuite-eps", "help": "accuracy of the scaled residuals (default 1e-12)"}
    )
    max_iter: int = field(
        default=1000, metadata={"flag": "--proxsuite-max-iter", "help": "iterations per solve (default 1000)"}
    )
    direct: bool = field(
        default=True,
        metadata={
            "flag": "--proxsuite-qp-only",
            "help": "every solve by ProxQP (default: equality rows independent by a margin are solved by Cholesky "
            "factors, the same solution at a fraction of the cost)",
        },
    )

    def __post_init__(self) -> None:
        if not (isinstance(self.eps_abs, float | int) and 0 < self.eps_abs < 1):
            raise ValueError(f"eps_abs must be in (0, 1), got {self.eps_abs!r}")
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise ValueError(f"max_iter must be an integer >= 1, got {self.max_iter!r}")
        if not isinstance(self.direct, bool):
            raise ValueError(f"direct must be true or false, got {self.direct!r}")


@dataclass(frozen=True)
class _Scaling:
    """Diagonal scalings: a = x / column, objective / inertia, rows / row; with the factors the
    equality form multiplies by (computed once: the scaling is refreshed every RESCALE_EVERY solves,
    it only needs the right orders of magnitude)."""

    column: np.ndarray
    inertia: float
    row: np.ndarray
    hessian_factor: np.ndarray
    gradient_factor: np.ndarray
    rows_factor: np.ndarray

    @classmethod
    def of(cls, problem: KKTProblem) -> _Scaling:
        diagonal = np.diagonal(problem.mass_matrix)
        inertia = float(diagonal.sum()) / len(diagonal)
        if not (inertia > 0 and float(diagonal.min()) > 0):
            raise SolverError("proxsuite: the joint-space inertia matrix has a non-positive diagonal")
        column = np.sqrt(diagonal / inertia)
        norms, significant = _row_sizes(problem.jacobian / column)
        row = np.where(significant, norms, float(np.max(norms, initial=0.0)) or 1.0)
        inverse = 1.0 / column
        return cls(
            column, inertia, row, np.outer(inverse, inverse) / inertia, inverse / inertia, np.outer(1.0 / row, inverse)
        )

    def fits(self, problem: KKTProblem) -> bool:
        """Whether the problem has the shape these scalings were made for."""
        return self.rows_factor.shape == problem.jacobian.shape


def _row_sizes(jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row's largest entry (of G with its columns scaled) and whether it is above :data:`ROUNDING_ROW` of the
    largest row's (False: rounding of a row that is zero here)."""
    norms = np.max(np.abs(jacobian), axis=1, initial=0.0)
    return norms, norms > ROUNDING_ROW * float(np.max(norms, initial=0.0))


def _force_rows(problem: KKTProblem, scaling: _Scaling, with_cones: bool = True) -> list[tuple[str, int, np.ndarray]]:
    """The sign and cone rows on the scaled forces z = lambda * row / inertia, ``block @ z <= 0``, with the contact
    each belongs to and its (first) row: a unilateral row's ``-z <= 0``, and ``with_cones`` a cone's inscribed
    pyramid (facets of unit norm) and ``-f_n <= 0``."""
    s = problem.jacobian.shape[0]
    rows = []
    for index in np.flatnonzero(problem.layout.unilateral):
        sign = np.zeros((1, s))
        sign[0, index] = -1.0  # lambda >= 0
        rows.append((problem.layout.names[index], int(index), sign))
    for cone in problem.layout.cones if with_cones else ():
        facets = cone.cone.facet_matrix / scaling.row[list(cone.rows)]
        block = np.zeros((facets.shape[0] + 1, s))
        block[:-1, list(cone.rows)] = facets / np.linalg.norm(facets, axis=1, keepdims=True)
        block[-1, cone.rows[0]] = -1.0  # f_n >= 0
        rows.append((cone.name, cone.rows[0], block))
    return rows


def direct_solve(problem: KKTProblem) -> tuple[np.ndarray, np.ndarray] | None:
    """(a, lambda) of the equality KKT system through Cholesky factors of M and of the Delassus matrix
    D = G M^-1 G^T: ``lambda = D^-1 (rhs - G M^-1 f)``, ``a = M^-1 (f + G^T lambda)``, over the rows that are not
    rounding of zero rows (:data:`ROUNDING_ROW`; their multipliers 0); None when M is not positive definite or D's
    smallest pivot (squared diagonal of its factor) is below :data:`DIRECT_PIVOT` of its largest diagonal entry (rows
    dependent or nearly so: ProxQP's proximal solve takes those). The solve is the core kernel's
    (:func:`pinstab.kernels.direct_solve`, ``cpp/kkt_solve.cpp``)."""
    kept = _row_sizes(problem.jacobian / np.sqrt(np.diagonal(problem.mass_matrix)))[1]  # _Scaling's columns
    solved = kernels.direct_solve(
        problem.mass_matrix, problem.free_force, problem.jacobian[kept], problem.rhs[kept], DIRECT_PIVOT
    )
    if solved is None:
        return None
    multipliers = np.zeros(len(kept))
    multipliers[kept] = solved[1]
    return solved[0], multipliers


class ProxsuiteSolver(KKTSolver):
    """ProxQP dense backend.

    Args:
        options: :class:`ProxsuiteOptions`.
    """

    name = "proxsuite"
    row_kinds = frozenset({RowKind.EQUALITY, RowKind.UNILATERAL, RowKind.CONE})

    def __init__(self, options: ProxsuiteOptions | None = None) -> None:
        super().__init__()
        self.options = options or ProxsuiteOptions()
        self._qp: proxsuite.proxqp.dense.QP | None = None
        self._shape: tuple[int, int, int] | None = None
        self._scaling: _Scaling | None = None
        self._scaled_solves = 0

    def _scaling_for(self, problem: KKTProblem) -> _Scaling:
        """The problem's scaling, computed afresh every RESCALE_EVERY solves or when the shape changes."""
        if self._scaling is None or self._scaled_solves >= RESCALE_EVERY or not self._scaling.fits(problem):
            self._scaling, self._scaled_solves = _Scaling.of(problem), 0
        self._scaled_solves += 1
        return self._scaling

    def _fresh(
        self, n: int, n_eq: int, n_in: int, closest_feasible: bool, proven: bool = False
    ) -> proxsuite.proxqp.dense.QP:
        qp = proxsuite.proxqp.dense.QP(n, n_eq, n_in)
        qp.settings.eps_abs = self.options.eps_abs
        qp.settings.eps_rel = self.options.eps_abs
        qp.settings.verbose = False
        qp.settings.max_iter = self.options.max_iter
        qp.settings.max_iter_in = MAX_ITER_IN
        # at a singular configuration -gamma0 can leave range(G) by rounding: take the closest
        # feasible accelerations (least-squares constraint rows) instead of declaring infeasibility
        qp.settings.primal_infeasibility_solving = closest_feasible
        if proven:  # a linear program found the rows feasible: ProxQP's certificate of the contrary is rounding
            qp.settings.eps_primal_inf = 0.0
        return qp

    def _run(
        self, matrices: tuple, n_in: int, closest_feasible: bool, proven: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Solve (warm start when the shape is unchanged, one cold retry; ``proven``: the rows are known feasible);
        returns (x, y, z)."""
        hessian, gradient, a_eq, b_eq, c_in, upper = matrices
        n, n_eq = hessian.shape[0], a_eq.shape[0]
        shape = (n, n_eq, n_in)
        lower = None if c_in is None else np.full(n_in, -1e30)
        if self._qp is None or self._shape != shape:
            self._qp, self._shape = self._fresh(n, n_eq, n_in, closest_feasible, proven), shape
            self._qp.init(hessian, gradient, a_eq, b_eq, c_in, lower, upper)
        else:
            self._qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            self._qp.update(hessian, gradient, a_eq, b_eq, c_in, lower, upper)
        self._qp.solve()
        if self._qp.results.info.status not in _SOLVED:
            # a warm start far from the answer (a state changing fast) can stall: retry cold
            self._qp = self._fresh(n, n_eq, n_in, closest_feasible, proven)
            self._qp.init(hessian, gradient, a_eq, b_eq, c_in, lower, upper)
            self._qp.solve()
        results = self._qp.results
        return np.array(results.x), np.array(results.y), np.array(results.z)

    def solve(self, problem: KKTProblem) -> KKTSolution:
        if problem.layout.equality_only and self.options.direct:
            direct = direct_solve(problem)
            if direct is not None:
                acceleration, multipliers = direct
                primal = primal_residual(problem, acceleration)
                if primal <= ACCEPTED_RESIDUAL:
                    return self.record(KKTSolution(acceleration, multipliers, DIRECT_STATUS, 0, primal, math.nan))
        scaling = self._scaling_for(problem)
        if problem.layout.equality_only:
            solution, accepted = self._judged(problem, *self._solve_equalities(problem, scaling))
        else:
            solution, accepted = self._judged(problem, *self._solve_with_inequalities(problem, scaling))
            if solution.status not in _SOLVED_NAMES:
                if not accepted:
                    self._explain_forces(problem)  # the contacts cannot hold: ContactInfeasibleError, naming them
                # they can: ProxQP did not finish forces pinned against a cone (a corner clamped between a ceiling and
                # the floor), which the tiny regularization leaves nearly a linear program; retry cold, better posed.
                # Even an answer accepted by its residuals is retried: whether ProxQP finishes such a problem turns
                # on rounding, and its unfinished answers (dual residual ~1e-9) set a clamped box moving at 1e-12 m
                unfinished = solution, accepted
                self._qp = None
                solution, accepted = self._judged(problem, *self._solve_with_inequalities(problem, scaling, retry=True))
                if not accepted:
                    solution, accepted = unfinished
        if not accepted:
            self._refuse(problem, solution)
        return self.record(solution)

    def _judged(
        self, problem: KKTProblem, acceleration: np.ndarray, multipliers: np.ndarray
    ) -> tuple[KKTSolution, bool]:
        """The last ProxQP solve's answer and whether it is accepted: solved, or its residuals (recomputed on the
        unscaled problem) below :data:`~pinstab.solvers.base.ACCEPTED_RESIDUAL` with every cone and sign kept."""
        info = self._qp.results.info
        if info.status in _SOLVED:
            # ProxQP met eps_abs + eps_rel on the scaled problem, whose terms are of order one: its own
            # residuals are relative ones, and computing them again would cost more than the solve
            return KKTSolution(
                acceleration, multipliers, info.status.name, int(info.iter), info.pri_res, info.dua_res
            ), True
        primal, dual = residuals(problem, acceleration, multipliers)
        solution = KKTSolution(acceleration, multipliers, info.status.name, int(info.iter), primal, dual)
        inside = problem.layout.equality_only or self._inside_cones(problem, multipliers)
        return solution, primal <= ACCEPTED_RESIDUAL and dual <= ACCEPTED_RESIDUAL and inside

    # -- equality rows: Gauss in the accelerations -------------------------------------------------
    def _solve_equalities(self, problem: KKTProblem, scaling: _Scaling) -> tuple[np.ndarray, np.ndarray]:
        hessian = problem.mass_matrix * scaling.hessian_factor
        gradient = -problem.free_force * scaling.gradient_factor
        rows = problem.jacobian * scaling.rows_factor
        x, y, _ = self._run((hessian, gradient, rows, problem.rhs / scaling.row, None, None), 0, True)
        return x / scaling.column, -scaling.inertia * y / scaling.row

    # -- unilateral and cone rows: accelerations and forces together ----------------------------------
    def _solve_with_inequalities(
        self, problem: KKTProblem, scaling: _Scaling, retry: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """(a, lambda) [m/s^2, rad/s^2; N, N m]; ``retry``: the contacts proven to hold, with
        :data:`RETRY_REGULARIZATION`."""
        regularization = RETRY_REGULARIZATION if retry else FORCE_REGULARIZATION
        matrices = self._inequality_qp(problem, scaling, regularization=regularization)
        x = self._run(*matrices, closest_feasible=False, proven=retry)[0]
        acceleration, forces = self._unscale(x, problem, scaling)
        return acceleration, self._smallest_forces(problem, scaling, forces)

    def _smallest_forces(self, problem: KKTProblem, scaling: _Scaling, forces: np.ndarray) -> np.ndarray:
        """The smallest forces with the resultant ``G^T forces`` that keep every cone and sign [N, N m], else
        ``forces``.

        The tiny regularization leaves the forces' null-space part (an internal force of a statically indeterminate
        contact set) converged only loosely, by however far ProxQP got. The least-squares (minimum-norm) forces are
        taken when they keep every cone and sign; otherwise (a clamp whose minimum-norm forces would pull) the
        smallest forces inside the cones, a QP on the scaled forces alone (identity Hessian: well-conditioned,
        unique), when ProxQP solves it.
        """
        resultant = problem.jacobian.T @ forces
        smallest = np.linalg.lstsq(problem.jacobian.T, resultant, rcond=None)[0]
        if self._inside_cones(problem, smallest):
            return smallest
        rows = problem.jacobian * scaling.rows_factor
        scaled = forces * scaling.row / scaling.inertia
        c_in = np.vstack([block for _, _, block in _force_rows(problem, scaling)])
        n, n_eq, n_in = len(forces), rows.shape[1], c_in.shape[0]
        qp = self._fresh(n, n_eq, n_in, closest_feasible=False)
        qp.init(np.eye(n), np.zeros(n), rows.T, rows.T @ scaled, c_in, np.full(n_in, -1e30), np.zeros(n_in))
        qp.solve()
        if qp.results.info.status not in _SOLVED:
            return forces
        polished = scaling.inertia * np.array(qp.results.x) / scaling.row
        return polished if self._inside_cones(problem, polished) else forces

    @staticmethod
    def _inequality_qp(
        problem: KKTProblem,
        scaling: _Scaling,
        with_cones: bool = True,
        regularization: float = FORCE_REGULARIZATION,
    ) -> tuple[tuple, int]:
        """The scaled (a, lambda) QP (``regularization``: eps on the scaled forces): its matrices and its number of
        inequalities."""
        nv, s = problem.mass_matrix.shape[0], problem.jacobian.shape[0]
        row = scaling.row
        rows = problem.jacobian * scaling.rows_factor  # A = R G C^-1, lambda = inertia * z / row
        hessian = np.zeros((nv + s, nv + s))
        hessian[:nv, :nv] = problem.mass_matrix * scaling.hessian_factor
        hessian[nv:, nv:] = regularization * np.eye(s)
        gradient = np.concatenate([-problem.free_force * scaling.gradient_factor, np.zeros(s)])
        unilateral = problem.layout.unilateral
        equal = ~unilateral
        newton_euler = np.hstack([hessian[:nv, :nv], -rows.T])
        accelerations = np.hstack([rows[equal], np.zeros((int(equal.sum()), s))])
        a_eq = np.vstack([newton_euler, accelerations])
        b_eq = np.concatenate([-gradient[:nv], (problem.rhs / row)[equal]])
        blocks, bounds = [], []
        picked = np.flatnonzero(unilateral)
        if picked.size:
            blocks.append(np.hstack([-rows[picked], np.zeros((picked.size, s))]))  # G a >= rhs
            bounds.append(-(problem.rhs / row)[picked])
        for _, _, block in _force_rows(problem, scaling, with_cones):
            blocks.append(np.hstack([np.zeros((block.shape[0], nv)), block]))
            bounds.append(np.zeros(block.shape[0]))
        c_in = np.vstack(blocks) if blocks else None
        upper = np.concatenate(bounds) if bounds else None
        n_in = 0 if c_in is None else c_in.shape[0]
        return (hessian, gradient, a_eq, b_eq, c_in, upper), n_in

    @staticmethod
    def _unscale(x: np.ndarray, problem: KKTProblem, scaling: _Scaling) -> tuple[np.ndarray, np.ndarray]:
        nv = problem.mass_matrix.shape[0]
        return x[:nv] / scaling.column, scaling.inertia * x[nv:] / scaling.row

    # -- judging ------------------------------------------------------------------------------------
    @staticmethod
    def _inside_cones(problem: KKTProblem, multipliers: np.ndarray) -> bool:
        """Every cone force inside its linearized cone and every unilateral multiplier >= 0 (to
        CONE_TOLERANCE of the largest force)."""
        scale = float(np.max(np.abs(multipliers), initial=0.0)) + float(np.max(np.abs(problem.free_force)))
        slack = CONE_TOLERANCE * scale
        if np.any(multipliers[problem.layout.unilateral] < -slack):
            return False
        for cone in problem.layout.cones:
            if np.max(cone.cone.facet_matrix @ multipliers[list(cone.rows)], initial=0.0) > slack:
                return False
        return True

    @staticmethod
    def _refuse(problem: KKTProblem, solution: KKTSolution) -> None:
        raise SolverError(
            f"proxsuite: ProxQP did not solve the constrained dynamics at t = {problem.t:.6g} s ({solution.status}, "
            f"relative residuals: constraint rows {solution.primal_residual:.3g}, equations of motion "
            f"{solution.dual_residual:.3g}; accepted: {ACCEPTED_RESIDUAL:g}). Either the constraints are inconsistent "
            "(conflicting closures, not merely redundant) or the run is blowing up (reduce dt or the gains)"
        )

    def _explain_forces(self, problem: KKTProblem) -> None:
        """Name the contacts that cannot hold, whatever ProxQP made of the problem.

        Whether they can is decided by a linear program (HiGHS: exact and deterministic, :meth:`_cannot_hold`);
        when they cannot, the contacts named are those whose force leaves its cone (or pulls) in the smallest
        forces that hold every contact without the cones (the Gauss solve without them), or when that solve names
        none, those the linear program found.

        Raises:
            ContactInfeasibleError: when some contact needs a force outside its cone or of the wrong sign.
        """
        scaling = self._scaling_for(problem)
        found = self._cannot_hold(problem, scaling)
        if not found:
            return
        x = self._run(*self._inequality_qp(problem, scaling, with_cones=False), closest_feasible=False)[0]
        self._qp, self._shape = None, None  # the next solve has cones again
        _, forces = self._unscale(x, problem, scaling)
        owned = _force_rows(problem, scaling)
        failing = _failing(problem, [(name, row) for name, row, _ in owned], forces) or found
        ranked = sorted(failing, key=_worst)
        described = "; ".join(_describe(name, cone, need) for need, name, cone in ranked)
        raise ContactInfeasibleError(
            f"sticking contacts cannot hold at t = {problem.t:.6g} s: {described}. The applied forces are outside "
            "the friction cone, so the contact would slide or open (held contacts cannot: plane contacts switch with "
            "--contacts event, simulate(contacts='event')); "
            "reduce the push or raise mu",
            [name for _, name, _ in ranked],
            problem.t,
        )

    def _cannot_hold(
        self, problem: KKTProblem, scaling: _Scaling
    ) -> list[tuple[tuple[float, bool], str, ConeRows | None]]:
        """The contacts that cannot hold (empty when all can, or when the program is not solved): a linear program
        on the scaled (a, lambda) rows with one slack per contact on its sign and cone rows, their sum minimized;
        a contact whose slack stays above :data:`CONE_TOLERANCE` of the forces in play needs a force outside its
        cone (or to pull), given with what it needs there."""
        (_, _, a_eq, b_eq, c_in, _), _ = self._inequality_qp(problem, scaling)
        owned = _force_rows(problem, scaling)
        nv, n, contacts = problem.mass_matrix.shape[0], a_eq.shape[1], len(owned)
        held = np.flatnonzero(problem.layout.unilateral)  # G a >= rhs, the first rows of c_in, kept exact
        slacks = [
            np.hstack([np.zeros((len(block), nv)), block, -np.eye(contacts)[[k] * len(block)]])
            for k, (_, _, block) in enumerate(owned)
        ]
        result = linprog(
            np.concatenate([np.zeros(n), np.ones(contacts)]),
            A_ub=np.vstack([np.hstack([c_in[: held.size], np.zeros((held.size, contacts))]), *slacks]),
            b_ub=np.concatenate([-(problem.rhs / scaling.row)[held], np.zeros(sum(len(b) for b in slacks))]),
            A_eq=np.hstack([a_eq, np.zeros((len(a_eq), contacts))]),
            b_eq=b_eq,
            bounds=[(None, None)] * n + [(0.0, None)] * contacts,
            method="highs",
        )
        if result.status != 0:
            return []
        x, excess = result.x[:n], result.x[n:]
        scale = float(np.max(np.abs(x[nv:]), initial=0.0)) + float(np.max(np.abs(b_eq[:nv]), initial=0.0))
        beyond = [
            (name, row) for (name, row, _), extra in zip(owned, excess, strict=True) if extra > CONE_TOLERANCE * scale
        ]
        return _failing(problem, beyond, self._unscale(x, problem, scaling)[1], strict=False)


def _failing(
    problem: KKTProblem, contacts: list[tuple[str, int]], forces: np.ndarray, strict: bool = True
) -> list[tuple[tuple[float, bool], str, ConeRows | None]]:
    """(what it needs, name, cone or None) of each contact in ``contacts`` (name, first row) once, kept when its
    force [N] leaves its linearized cone or pulls (all of them unless ``strict``)."""
    cones = {cone.name: cone for cone in problem.layout.cones}
    failing = {}
    for name, row in contacts:
        cone = cones.get(name)
        need = _needed(cone, row, forces)
        if not strict or need[1] or (cone is not None and need[0] > cone.cone.inscribed_mu):
            failing[name] = (need, name, cone)
    return list(failing.values())


def _needed(cone: ConeRows | None, row: int, forces: np.ndarray) -> tuple[float, bool]:
    """(|f_t| / f_n the contact needs, whether it needs to pull) of a cone, or of the unilateral ``row`` (no
    friction: 0) when ``cone`` is None."""
    if cone is None:
        return 0.0, bool(forces[row] < 0)
    normal, first, second = forces[list(cone.rows)]
    tangential = math.hypot(first, second)
    if normal <= 0:
        return (math.inf if tangential > 0 else 0.0), normal < 0
    return tangential / normal, False


def _worst(item: tuple[tuple[float, bool], str, ConeRows | None]) -> tuple[float, str]:
    return -item[0][0], item[1]


def _describe(name: str, cone: ConeRows | None, need: tuple[float, bool]) -> str:
    if need[1] or cone is None:
        return f"contact {name!r} would need to pull (negative normal force)"
    return (
        f"contact {name!r} needs |f_t|/f_n = {need[0]:.4g} > mu = {cone.cone.mu:g} "
        f"(linearized {cone.cone.inscribed_mu:.4g} with {cone.cone.facets} facets)"
    )


_SOLVED = (
    proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED,
    proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE,
)
_SOLVED_NAMES = frozenset(status.name for status in _SOLVED)
LIMIT_STATUS = proxsuite.proxqp.QPSolverOutput.PROXQP_MAX_ITER_REACHED.name
"""The status of a solve ProxQP ended at its iteration limit (accepted or not by its residual)."""


@SOLVERS.register(
    "proxsuite",
    options=ProxsuiteOptions,
    summary="ProxQP: redundancy, singularities, contacts, cones",
    capabilities=ProxsuiteSolver.row_kinds,
)
def make_proxsuite(
    model: ConstrainedModel, corrector_gains: tuple[float, float] | None, options: ProxsuiteOptions
) -> ProxsuiteSolver:
    """The ProxQP backend (takes every row kind)."""
    return ProxsuiteSolver(options)
