"""Contact forces that hold a load, on the exact round friction cones [MLS ch. 5]: the squeeze a grasp
needs, the forces closest to a wished squeeze, and which contacts leave their cones.

A grasp is given by its *carrier* A (k x m), which takes the contact forces (each contact's components in
its frame C_i, z the normal into the object, stacked in contact order [N, N m]) to the generalized force
they exert on the object, and by its contacts (objects with ``name``, ``model``, ``mu``, ``torsion``: a
:class:`~pinstab.grasp.analysis.GraspContact` or a fingertip constraint block). Forces ``lambda`` hold
the load ``w`` (k,) when ``A lambda = w`` and every contact carries its force: ``f_n >= 0``,
``|f_t| <= mu f_n`` (the round cone) and, for a soft finger, ``|m_z| <= torsion f_n``; a rigid contact
carries anything. The *squeeze* of ``lambda`` is its largest normal force [N].

Method: Clarabel, an interior-point solver for conic programs, on the exact round cones (a second-order cone
``(mu f_n, f_t1, f_t2)`` per friction contact, linear rows for torsion, normal forces and the cap) with a linear
objective (the squeeze, or the distance to the wished forces through one more second-order cone), its answer kept
only when this module's own checks pass (the load carried within :data:`FEASIBILITY`, :class:`ConeTest`); for the
squeeze, after a numerical failure, the forces of a linear program on the inscribed pyramids (HiGHS), when they hold.
It replaced SciPy's SLSQP on the quadratic form ``mu^2 f_n^2 >= |f_t|^2``, whose constraint gradient vanishes at a
cone's apex: near a grasp's let-go, where contacts unload, 179 of 631 solves of allegro-drop's first 0.3 s ran to
SLSQP's 500 iterations and 161 more stopped on a failed line search (45 of 55 CPU s of the run).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from .. import kernels
from ..conic import INFEASIBLE, PRIMAL_INFEASIBLE, SOLVED, conic_solve
from ..contact.cones import FrictionCone
from ..contact.models import WRENCH_BASES, ContactLimits
from ..proxqp import proxsuite
from .analysis import RANK_TOLERANCE

START_FACETS = 16  # sides of the pyramids whose linear program is the squeeze solve's fallback
CONIC_TOLERANCE = 1e-11  # Clarabel's gap and feasibility tolerances (relative to the problem's scale)
FEASIBILITY_TOLERANCE = 1e-8  # Clarabel's tolerances where it only decides whether rows can hold (its default)
FEASIBILITY = 1e-9  # relative to the load: residuals and cone margins above -this hold
QP_ITERATIONS = 200  # a small QP converges in tens of iterations; an infeasible one would run for minutes
ACTIVE_SET_TOLERANCE = 1e-10  # relative to the largest entry: bounds and multiplier signs of a previous active set
COMPLEMENTARITY = 1e-6  # relative to the bound: a row with a multiplier farther from its bound was left by it
# relative: a grasp-hold chooses its forces in cones (and torsion limits) this much narrower than the contacts', so that
# no contact it holds sits on its cone's edge, where rounding (the solves' 1e-13, FEASIBILITY's 1e-9 N) decides
# whether it slips; 1000 times FEASIBILITY, and the hold lets go that much earlier (tilt_at_first_slip)
HOLD_MARGIN = 1e-6
UNBOUNDED = 1e30  # ProxQP's infinite bound
_SOLVED = (proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED,)


class ConeColumns(NamedTuple):
    """Where one contact's force sits in the stacked forces, for the limits it must keep.

    Attributes:
        name: the contact. mu: [-]. torsion: [m]. normal: column of f_n. tangents: columns of (f_t1, f_t2),
        or None (frictionless). spin: column of m_z (soft finger), or None. model: the contact model.
    """

    name: str
    mu: float
    torsion: float
    normal: int
    tangents: tuple[int, int] | None
    spin: int | None
    model: str


class Limits(NamedTuple):
    """A contact's limits as this module reads them: name, model (a key of ``WRENCH_BASES``), mu [-], torsion [m]."""

    name: str
    model: str
    mu: float
    torsion: float


def narrowed(contacts: list[Any], margin: float) -> list[Limits]:
    """The contacts' limits with their friction and torsion coefficients ``margin`` (relative) smaller: forces inside
    those keep ``margin`` mu f_n (and margin torsion f_n) from the contacts' own bounds."""
    scale = 1.0 - margin
    return [Limits(c.name, c.model, c.mu * scale, c.torsion * scale) for c in contacts]


def cone_columns(contacts: list[Any]) -> tuple[list[ConeColumns], int]:
    """(the limited contacts' columns (rigid contacts carry anything: none), the number of force columns)."""
    found, offset = [], 0
    for contact in contacts:
        components = [int(k) for k in np.flatnonzero(WRENCH_BASES[contact.model].any(axis=1))]
        column = {component: offset + k for k, component in enumerate(components)}
        offset += len(components)
        if contact.model != "rigid":
            tangents = (column[0], column[1]) if 0 in column else None
            limits = (contact.mu, contact.torsion, column[2], tangents, column.get(5), contact.model)
            found.append(ConeColumns(contact.name, *limits))
    return found, offset


def pyramid_rows(columns: list[ConeColumns], count: int, facets: int, widen: float = 1.0) -> np.ndarray:
    """Rows C with ``C lambda >= 0`` inside every contact's limits with its cone linearized by the pyramid of
    ``facets`` sides inscribed in the cone of ``widen * mu`` (``1 / cos(pi / facets)``: circumscribed),
    rows of unit length (their values are distances [N or N m]): facets, then the normal force, then a
    soft finger's two torsion bounds."""
    rows = []
    for contact in columns:
        if contact.tangents is not None:
            cone = FrictionCone(widen * contact.mu, facets)
            for facet in -cone.facet_matrix / math.sqrt(1.0 + cone.inscribed_mu**2):
                row = np.zeros(count)
                row[[contact.normal, *contact.tangents]] = facet
                rows.append(row)
        row = np.zeros(count)
        row[contact.normal] = 1.0
        rows.append(row)
        if contact.spin is not None:
            for sign in (1.0, -1.0):
                row = np.zeros(count)
                row[[contact.normal, contact.spin]] = [contact.torsion, sign]
                rows.append(row / math.hypot(contact.torsion, 1.0))
    return np.array(rows).reshape(-1, count)


def normal_columns(columns: list[ConeColumns]) -> list[int]:
    """The columns of the normal forces."""
    return [contact.normal for contact in columns]


def cone_margins(contacts: list[Any], forces: np.ndarray) -> dict[str, dict[str, float]]:
    """Each limited contact's margins for the stacked ``forces``: ``normal`` f_n [N], ``friction``
    mu f_n - |f_t| [N] (friction contacts), ``torsion`` torsion f_n - |m_z| [N m] (soft fingers); >= 0 inside
    (:meth:`~pinstab.contact.models.ContactLimits.margins`, the compiled rule)."""
    columns, _ = cone_columns(contacts)
    found = {}
    for contact in columns:
        wrench = np.zeros(6)  # (f_t1, f_t2, f_n, 0, 0, m_z) in C
        wrench[2] = forces[contact.normal]
        if contact.tangents is not None:
            wrench[:2] = forces[list(contact.tangents)]
        if contact.spin is not None:
            wrench[5] = forces[contact.spin]
        limits = ContactLimits(contact.name, contact.model, contact.mu, contact.torsion, "", "")
        found[contact.name] = limits.margins(wrench)
    return found


NO_COLUMN = -1  # a frictionless contact's tangent columns, a contact's spin column but a soft finger's


def cone_arrays(columns: list[ConeColumns]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The contacts' columns as the compiled cone test reads them: (rows (normal, tangent, tangent, spin; -1: none)
    (k x 4, int32), mu (k,) [-], torsion (k,) [m])."""
    rows = [
        [c.normal, *(c.tangents or (NO_COLUMN, NO_COLUMN)), NO_COLUMN if c.spin is None else c.spin] for c in columns
    ]
    return (
        np.array(rows, dtype=np.int32).reshape(-1, 4),
        np.array([c.mu for c in columns], dtype=float),
        np.array([c.torsion for c in columns], dtype=float),
    )


class ConeTest:
    """Whether stacked forces keep every contact's limits (each of its margins, :func:`cone_margins`, above a rounding
    slack of FEASIBILITY (1 + the largest |force|)) and every normal force within a cap [N] (inf: none): the compiled
    test (``cpp/grasp_forces.cpp`` cones_hold, the core's too), at every evaluation."""

    def __init__(self, contacts: list[Any], cap: float = math.inf) -> None:
        self._columns, self._mu, self._torsion = cone_arrays(cone_columns(contacts)[0])
        self._cap = float(cap)

    def holds(self, forces: np.ndarray) -> bool:
        """No contact leaves its limits and no normal force exceeds the cap by more than 1e-9 of it; False where a
        force is not a number."""
        return kernels.cones_hold(self._columns, self._mu, self._torsion, self._cap, FEASIBILITY, forces)


@dataclass(frozen=True)
class Holding:
    """Contact forces that hold a load, or the answer that none do.

    Attributes:
        forces: the stacked contact forces in their contact frames [N, N m], or None when none hold the load.
        squeeze: their largest normal force [N] (inf when none hold the load).
    """

    forces: np.ndarray | None
    squeeze: float

    @property
    def holds(self) -> bool:
        """Whether some forces inside the cones hold the load."""
        return self.forces is not None


class _Problem:
    """Variables x = (lambda / scale, s / scale): A lambda = w, the limits, f_n <= s <= cap [N]."""

    def __init__(self, carrier: np.ndarray, load: np.ndarray, contacts: list[Any], cap: float) -> None:
        self.carrier, self.load, self.cap = np.asarray(carrier, float), np.asarray(load, float), cap
        self.cone_test = ConeTest(contacts)  # the limits a solution must keep
        self.columns, count = cone_columns(contacts)
        if count != self.carrier.shape[1]:
            raise ValueError(f"the contacts have {count} force components, the carrier {self.carrier.shape[1]} columns")
        self.count = count
        self.scale = 1.0 + float(np.max(np.abs(self.load), initial=0.0))
        normals = [contact.normal for contact in self.columns]
        self.caps = np.zeros((len(normals), count + 1))  # s - f_n >= 0
        self.caps[np.arange(len(normals)), normals] = -1.0
        self.caps[:, -1] = 1.0
        # A lambda = w on the independent rows of A (independent rows for the solvers); w outside A's range: nothing
        # holds
        left, singular, _ = np.linalg.svd(self.carrier, full_matrices=False)
        rank = int(np.count_nonzero(singular > RANK_TOLERANCE * max(float(singular[0]), 1.0)))
        self.reachable = bool(
            np.linalg.norm(self.load - left[:, :rank] @ (left[:, :rank].T @ self.load)) <= FEASIBILITY * self.scale
        )
        self.equality = np.hstack([left[:, :rank].T @ self.carrier, np.zeros((rank, 1))])
        self.rhs = left[:, :rank].T @ self.load / self.scale
        # the linear program's bounds: f_n >= 0, 0 <= s <= cap
        self.bounds = [(None, None)] * count + [(0.0, None if math.isinf(cap) else cap / self.scale)]
        for normal in normals:
            self.bounds[normal] = (0.0, None)

    def start(self) -> tuple[np.ndarray, bool] | None:
        """(x of the linear program min s on the inscribed pyramids, True) or, when those hold nothing, on
        the circumscribed ones (False); None when neither holds the load (then the round cones do not)."""
        from scipy.optimize import linprog

        cost = np.zeros(self.count + 1)
        cost[-1] = 1.0
        for widen in (1.0, 1.0 / math.cos(math.pi / START_FACETS)):
            pyramids = pyramid_rows(self.columns, self.count, START_FACETS, widen)
            inside = np.hstack([-pyramids, np.zeros((len(pyramids), 1))])
            upper = np.vstack([inside, -self.caps])
            result = linprog(
                cost,
                A_ub=upper,
                b_ub=np.zeros(len(upper)),
                A_eq=self.equality,
                b_eq=self.rhs,
                bounds=self.bounds,
                method="highs",
            )
            if result.status == 0:
                return result.x, widen == 1.0
        return None

    def cone_rows(self, squeeze: bool) -> tuple[np.ndarray, np.ndarray, list[tuple[str, int]]]:
        """The problem's constraints as Clarabel takes them, ``G x + slack = h`` with the slack in the cones: the
        independent rows of ``A lambda = w`` (zero cone); ``f_n >= 0``, a soft finger's ``torsion f_n -+ m_z >= 0``
        and, with the squeeze s among the variables (``squeeze``: x = (lambda, s) / scale), ``s - f_n >= 0``,
        ``s >= 0`` and, with a cap, ``s <= cap``, without it (x = lambda / scale: an objective that does not read s
        leaves it undetermined, which ended interior-point solves in numerical errors) ``f_n <= cap`` (non-negative
        cone); each friction contact's ``(mu f_n, f_t1, f_t2)`` (a second-order cone of dimension 3). Returns (G, h,
        cones: (kind, size) as :func:`~pinstab.conic.conic_solve` takes them)."""
        width = self.count + 1 if squeeze else self.count
        rows, bounds = [-self.equality[:, :width]], [-self.rhs]
        nonnegative = []
        for contact in self.columns:
            nonnegative.append(np.eye(width)[contact.normal])
            if contact.spin is not None:
                for sign in (1.0, -1.0):
                    row = np.zeros(width)
                    row[[contact.normal, contact.spin]] = [contact.torsion, -sign]
                    nonnegative.append(row)
        if squeeze:
            nonnegative.extend(self.caps)
            nonnegative.append(np.eye(width)[-1])
        upper: list[np.ndarray] = []  # rows that the cap bounds: s, else every f_n
        if not math.isinf(self.cap):
            upper = [-np.eye(width)[-1]] if squeeze else [-np.eye(width)[c.normal] for c in self.columns]
        rows.append(-np.array(nonnegative + upper))
        bounds.append(np.concatenate([np.zeros(len(nonnegative)), np.full(len(upper), self.cap / self.scale)]))
        cones = [("zero", len(self.rhs)), ("nonnegative", len(nonnegative) + len(upper))]
        for contact in self.columns:
            if contact.tangents is not None:
                cone = np.zeros((3, width))
                cone[0, contact.normal] = contact.mu
                cone[1, contact.tangents[0]] = cone[2, contact.tangents[1]] = 1.0
                rows.append(-cone)
                bounds.append(np.zeros(3))
                cones.append(("second-order", 3))
        return np.vstack(rows), np.concatenate(bounds), cones

    def solve(self, target: np.ndarray | None = None) -> Holding:
        """Minimize the last variable on the round cones by Clarabel (an interior-point method for conic programs: the
        exact second-order cones, to :data:`CONIC_TOLERANCE`): without ``target``, the squeeze s (x = (lambda, s) /
        scale); with it (forces / scale), the distance r from it (x = (lambda, r) / scale, ``(r, lambda - target)`` in a
        second-order cone: the least-squares objective as a linear one, which Clarabel solves where the quadratic
        objective's form ended 432 of 817 solves near allegro-drop's let-go in numerical errors). Its answer is kept
        when it passes this module's own checks (the load within :data:`FEASIBILITY`, :class:`ConeTest`); else,
        without a target, where Clarabel failed numerically (not where it proved the problem infeasible), the linear
        program's forces on the inscribed pyramids (:meth:`start`), when they hold."""
        if not self.reachable:
            return Holding(None, math.inf)
        matrix, bounds, cones = self.cone_rows(target is None)
        count = self.count
        if target is not None:
            distance = np.zeros((count + 1, count + 1))  # G rows of the slack (r, lambda - target) = h - G (x, r)
            distance[0, -1] = -1.0
            distance[1:, :count] = -np.eye(count)
            matrix = np.vstack([np.hstack([matrix, np.zeros((len(matrix), 1))]), distance])
            bounds = np.concatenate([bounds, [0.0], -target])
            cones = [*cones, ("second-order", count + 1)]
        status, x = conic_solve(np.eye(count + 1)[-1], matrix, bounds, cones, CONIC_TOLERANCE)
        return self._kept(status, x, target is None)

    def _kept(self, status: str, x: np.ndarray, fallback: bool) -> Holding:
        """The forces of Clarabel's answer x (its status) when they pass the checks; else, with ``fallback`` after a
        numerical failure, the inscribed pyramids' linear program's."""
        candidates = [x] if status in SOLVED else []
        if fallback and status not in SOLVED + INFEASIBLE:  # a numerical failure: the pyramids may hold
            start = self.start()
            candidates = [start[0]] if start is not None and start[1] else []
        for x in candidates:
            forces = x[: self.count] * self.scale
            residual = float(np.max(np.abs(self.carrier @ forces - self.load), initial=0.0))
            if residual <= FEASIBILITY * self.scale and self.cone_test.holds(forces):
                normals = [contact.normal for contact in self.columns]
                return Holding(forces, float(np.max(forces[normals], initial=0.0)))
        return Holding(None, math.inf)


def least_squeeze(carrier: np.ndarray, load: np.ndarray, contacts: list[Any]) -> Holding:
    """The contact forces that hold ``load`` (A lambda = w) with the smallest largest normal force: the
    squeeze [N] the grasp needs; ``Holding(None, inf)`` when no forces inside the cones hold it."""
    return _Problem(carrier, load, contacts, math.inf).solve()


def closest_holding(
    carrier: np.ndarray, load: np.ndarray, contacts: list[Any], target: np.ndarray, cap: float = math.inf
) -> Holding:
    """The contact forces that hold ``load`` inside the cones with every normal force at most ``cap`` [N],
    closest (least squares) to ``target`` (stacked forces [N, N m]); ``Holding(None, inf)`` when none do (or, where
    the load is barely held, when the interior-point solve does not reach its tolerance: :func:`least_squeeze` is
    the robust test of whether any forces hold, and its forces the fallback)."""
    problem = _Problem(carrier, load, contacts, cap)
    return problem.solve(np.asarray(target, float) / problem.scale)


def feasible(
    equality: np.ndarray, rhs: np.ndarray, inequality: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> bool:
    """Whether some x has ``E x = b`` and ``l <= C x <= u`` (bounds of :data:`UNBOUNDED` size: none), by Clarabel on
    the rows without cost (where a failing ProxQP runs to its iteration cap, ~10 ms on a grasp's pyramids).
    False only where Clarabel proves the rows infeasible (a certificate to its default 1e-8, looser than the QPs'
    eps_abs 1e-10), so that rows it finds infeasible no QP here solves."""
    finite_upper, finite_lower = np.abs(upper) < UNBOUNDED, np.abs(lower) < UNBOUNDED
    rows = np.vstack([equality, inequality[finite_upper], -inequality[finite_lower]])
    bounds = np.concatenate([rhs, upper[finite_upper], -lower[finite_lower]])
    cones = [("zero", len(rhs)), ("nonnegative", len(bounds) - len(rhs))]
    status, _ = conic_solve(np.zeros(inequality.shape[1]), rows, bounds, cones, FEASIBILITY_TOLERANCE)
    return status != PRIMAL_INFEASIBLE  # a certificate (not the reduced-accuracy AlmostPrimalInfeasible)


def _fresh_qp(variables: int, equalities: int, inequalities: int) -> proxsuite.proxqp.dense.QP:
    """A dense ProxQP of that shape with this module's settings (see :class:`WarmQP`)."""
    qp = proxsuite.proxqp.dense.QP(variables, equalities, inequalities)
    qp.settings.eps_abs = 1e-10
    qp.settings.verbose = False
    qp.settings.max_iter, qp.settings.max_iter_in = QP_ITERATIONS, QP_ITERATIONS
    return qp


class WarmQP:
    """ProxQP (dense) on ``min x^T H x / 2 + g^T x``, ``E x = b``, ``l <= C x <= u`` for a caller that solves a
    QP of one shape at successive states (a force element at every evaluation), without Ruiz equilibration
    (problems here are in N and N m already) and with a capped iteration count (an infeasible problem stops
    early). Each solve starts from the previous solution and multipliers (ProxQP's warm start; a cold
    start converges to the same ``eps_abs`` 1e-10); the QP is built afresh, cold, when the shape changes
    or a warm solve does not converge.

    Before ProxQP, the last ProxQP solution's active set is tried (the rows at a bound with a multiplier pushing
    them there): the equality-constrained QP with those rows held at their bounds, one KKT solve. When its x keeps
    every other row within its bounds and its multipliers keep their signs (to :data:`ACTIVE_SET_TOLERANCE`), it
    satisfies the QP's optimality conditions and is its solution (the same to ProxQP's 1e-10); the active set of
    a grasp changes rarely between evaluations, so ProxQP runs only where it does. A warm ProxQP result whose
    multipliers push rows that left their bounds is refused (:func:`_complementary`) and solved cold."""

    def __init__(self) -> None:
        self._qp: proxsuite.proxqp.dense.QP | None = None
        self._shape: tuple[int, int, int] = (0, 0, 0)
        self._active: tuple[np.ndarray, np.ndarray] | None = None  # (row indices, +1 upper / -1 lower bound)
        self._failed = False  # whether the last solve failed
        self._unsolved: tuple[np.ndarray, ...] | None = None  # the last failing problem, screened out, not yet solved

    def solve(
        self, hessian, gradient, equality, rhs, inequality, lower, upper, screen: bool = False
    ) -> tuple[np.ndarray, bool, Any]:
        """(x, solved, ProxQP's info: None when the previous active set gave x or the screen refused the problem).

        With ``screen``, after a failed solve a problem whose rows an LP finds infeasible (:func:`feasible`) is not
        given to ProxQP (which would run to its iteration cap, warm and then cold: ~20 ms on a grasp's pyramids, the
        LP ~1 ms): it fails at once (x NaN), and it is solved cold only when a later problem is given to ProxQP, which
        then warm-starts from it as it would have (the same solutions to the last bit)."""
        shape = (len(gradient), equality.shape[0], inequality.shape[0])
        problem = (hessian, gradient, equality, rhs, inequality, lower, upper)
        if screen and self._failed and shape == self._shape and not feasible(equality, rhs, inequality, lower, upper):
            self._unsolved = tuple(np.array(part) for part in problem)
            return np.full(len(gradient), np.nan), False, None
        if self._unsolved is not None:  # the failing problem screened out last: its cold solve, as it would have been
            self._cold(*self._unsolved)
            self._unsolved = None
        x, solved, info = self._solve(*problem)
        self._failed = not solved
        return x, solved, info

    def _solve(self, hessian, gradient, equality, rhs, inequality, lower, upper) -> tuple[np.ndarray, bool, Any]:
        """:meth:`solve` without the screen."""
        shape = (len(gradient), equality.shape[0], inequality.shape[0])
        if shape == self._shape and self._active is not None:
            x = _on_active_set(hessian, gradient, equality, rhs, inequality, lower, upper, *self._active)
            if x is not None:
                return x, True, None
        qp = self._qp
        if qp is not None and shape == self._shape:
            qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
            qp.update(hessian, gradient, equality, rhs, inequality, lower, upper, update_preconditioner=False)
            qp.solve()
            if qp.results.info.status in _SOLVED and _complementary(qp, inequality, lower, upper):
                return self._solved(qp), True, qp.results.info
        qp = self._cold(hessian, gradient, equality, rhs, inequality, lower, upper)
        solved = qp.results.info.status in _SOLVED
        return (self._solved(qp) if solved else np.array(qp.results.x)), solved, qp.results.info

    def _cold(self, hessian, gradient, equality, rhs, inequality, lower, upper) -> proxsuite.proxqp.dense.QP:
        """ProxQP built afresh for the problem and solved cold (no active set kept): the QP warm solves start from."""
        qp = self._qp = _fresh_qp(len(gradient), equality.shape[0], inequality.shape[0])
        self._shape = (len(gradient), equality.shape[0], inequality.shape[0])
        # no Ruiz equilibration: the problems are already in N and m (Hessian condition ~15 on allegro-lift), and
        # equilibrating them made the iteration count erratic (30 -> 400..13,000, varying with the CPU's vector
        # instructions and from run to run), so that a QP solved here could fail on another machine
        qp.init(hessian, gradient, equality, rhs, inequality, lower, upper, compute_preconditioner=False)
        qp.solve()
        self._active = None
        return qp

    def _solved(self, qp: proxsuite.proxqp.dense.QP) -> np.ndarray:
        """ProxQP's x, its active set kept for the next solve (multipliers z: H x + g + E^T y + C^T z = 0, z > 0 at an
        upper bound, z < 0 at a lower one)."""
        multipliers = np.array(qp.results.z)
        rows = np.flatnonzero(_pushed(multipliers))
        self._active = rows, np.sign(multipliers[rows])
        return np.array(qp.results.x)


def _pushed(multipliers: np.ndarray) -> np.ndarray:
    """The rows whose multiplier pushes them against a bound: beyond :data:`ACTIVE_SET_TOLERANCE` of the largest."""
    magnitude = np.abs(multipliers)
    return magnitude > ACTIVE_SET_TOLERANCE * max(1.0, float(np.max(magnitude, initial=0.0)))


def _complementary(qp: proxsuite.proxqp.dense.QP, inequality, lower, upper) -> bool:
    """Whether every row of C with a multiplier (beyond :data:`ACTIVE_SET_TOLERANCE` of the largest) sits at the
    bound it pushes against, to :data:`COMPLEMENTARITY` of that bound's size. ProxQP's stopping test reads the
    primal and dual residuals only: warm-started where just the bounds moved, it stops at iteration 0 on the
    previous x and multipliers, rows pushed against bounds they no longer touch (measured: a row 9 from its
    moved bound, ``tests/test_grasp_control.py``)."""
    multipliers, product = np.array(qp.results.z), inequality @ np.array(qp.results.x)
    gap = np.where(multipliers > 0, upper - product, product - lower)
    pushed = _pushed(multipliers)
    return bool(
        np.all(
            np.abs(gap[pushed])
            <= COMPLEMENTARITY * np.maximum(1.0, np.abs(np.where(multipliers > 0, upper, lower)[pushed]))
        )
    )


def _on_active_set(hessian, gradient, equality, rhs, inequality, lower, upper, rows, sides) -> np.ndarray | None:
    """The QP's solution when ``rows`` of C at their bounds (``sides``: +1 upper, -1 lower) are its active set: x of
    the KKT system [H E^T C_a^T; E 0 0; C_a 0 0] [x; y; z] = [-g; b; bounds], accepted when every row of C is within
    its bounds and every z has its side's sign (to :data:`ACTIVE_SET_TOLERANCE`); else None."""
    held = inequality[rows]
    constraints = np.vstack([equality, held])
    count, bound = len(gradient), len(constraints)
    matrix = np.zeros((count + bound, count + bound))
    matrix[:count, :count] = hessian
    matrix[:count, count:] = constraints.T
    matrix[count:, :count] = constraints
    values = np.where(sides > 0, upper[rows], lower[rows])
    try:
        solution = np.linalg.solve(matrix, np.concatenate([-gradient, rhs, values]))
    except np.linalg.LinAlgError:  # the held rows and E dependent: ProxQP decides
        return None
    x, z = solution[:count], solution[count + len(rhs) :]
    if not np.isfinite(solution).all():
        return None
    tolerance = ACTIVE_SET_TOLERANCE * max(1.0, float(np.max(np.abs(solution), initial=0.0)))
    product = inequality @ x
    if np.any(product < lower - tolerance) or np.any(product > upper + tolerance) or np.any(z * sides < -tolerance):
        return None
    if float(np.max(np.abs(equality @ x - rhs), initial=0.0)) > tolerance:
        return None
    return x
