"""The time-stepping contacts' step in NumPy and Pinocchio's Python bindings, as pinstab took it before the step was
compiled (cpp/cone_step.hpp): the second method the compiled step is checked against
(``tests/test_contact_stepping_compiled.py``) and timed against (``benchmarks/stepping_core.py``).

The same physics as :class:`~pinstab.integration.contact_stepping.ContactStepper` (its module says which), computed
another way: SciPy's Cholesky factor of M, the midpoint passes over ``pin.nonLinearEffects``, the Delassus matrix by
NumPy, ADMM through Pinocchio's Python bindings on the problem with steep cones scaled to 1, run from zero for
:data:`~pinstab.solvers.ncp.CHECK_EVERY` iterations, half as many, twice as many and so on, checked after each and
ended as the compiled solve ends, then PGS the same way
when ADMM's answer misses the contact law (:func:`~pinstab.solvers.ncp.ncp_residual` beyond
:data:`~pinstab.solvers.ncp.CHECK_RTOL` of the velocity scale), free flyers moved by ``pin.Quaternion``. A step whose
problem both miss raises :class:`~pinstab.errors.ContactSolveError` (a grown problem is given up for the one before
it, as the compiled step does).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from scipy.linalg import cho_factor, cho_solve

from ..errors import ContactSolveError
from ..integration.contact_stepping import IMPULSE_TOLERANCE, MIDPOINT_PASSES, MIDPOINT_TOLERANCE, ContactStepper
from ..integration.stepping import Failure
from ..solvers.contact_modes import ModeDynamics
from ..solvers.mode_choice import TOUCH_GAP
from ..solvers.ncp import (
    CHECK_EVERY,
    CHECK_RTOL,
    CONE_ROWS,
    ROUND_SETTLED,
    NcpSolver,
    admm_settings,
    friction_cones,
    ncp_residual,
)
from ..system import ConstrainedSystem
from .torsion_admm import torsion_admm, torsion_rows


class PythonStepper(ContactStepper):
    """:class:`~pinstab.integration.contact_stepping.ContactStepper` with its step's numbers in NumPy (the
    reference; same arguments).

    Attributes:
        free_flyers: (idx_q, idx_v) of the model's free-flyer joints. cones: the cone solve's constraint models by
            the friction coefficients of its contacts (built once each).
    """

    name = "moreau-jean-numpy"

    def __init__(self, system: ConstrainedSystem, dynamics: ModeDynamics, solver: NcpSolver) -> None:
        super().__init__(system, dynamics, solver)
        joints = system.model.model.joints[1:]
        self.free_flyers = [(j.idx_q, j.idx_v) for j in joints if j.shortname() == "JointModelFreeFlyer"]
        self.cones: dict[tuple[float, ...], tuple] = {}

    def step(self, q: np.ndarray, v: np.ndarray, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """One step of ``dt`` [s] from (q, v) at t [s]; returns (q+, v+)."""
        terms, contacts = self.start(q, v, t, dt)
        factor, force = cho_factor(terms.mass_matrix), terms.tau - terms.bias
        at_start = pin.nonLinearEffects(self.system.model.model, self.system.model.scratch, q, v).copy()
        k = len(contacts.gaps)
        jacobian = np.vstack([contacts.jacobian, contacts.spin_jacobian.reshape(-1, v.size)])  # then the torsions'
        mobility = cho_solve(factor, jacobian.T)
        change = mobility @ np.concatenate([self.impulses.reshape(-1), self.torques])  # the last step's impulses
        after = v + dt * (cho_solve(factor, force) - self._turn(v))  # each fixed point from the last
        for _ in range(MIDPOINT_PASSES):  # the midpoint over the impulses, as the compiled step
            v_free = self._free_velocity(q, v, dt, force, factor, at_start, change, after)
            impulses = self._contact_solve(contacts, jacobian, mobility, v_free, dt, t)
            v_new = v_free + mobility @ impulses
            if np.array_equal(v_new - v_free, change):  # solved from this midpoint (no impulse, or the guess's)
                break
            change = v_new - v_free
            after = self._free_velocity(q, v, dt, force, factor, at_start, change, v_free)
            if np.max(np.abs(after - v_free)) <= IMPULSE_TOLERANCE * max(np.max(np.abs(v_free)), np.max(np.abs(v_new))):
                break
        else:
            raise Failure(f"the velocity terms at the step's midpoint did not settle in {MIDPOINT_PASSES} passes")
        velocities = jacobian @ v_new
        normal = contacts.jacobian[0::3]
        reach_n = np.einsum("ij,ji->i", normal, mobility[:, : 3 * k : 3])
        linear = impulses[: 3 * k].reshape(-1, 3)
        self._track(t, dt, linear, velocities[: 3 * k].reshape(-1, 3), reach_n, impulses[3 * k :], velocities[3 * k :])
        return self._integrate(q, v_new, dt)

    def _contact_solve(
        self, contacts, jacobian: np.ndarray, mobility: np.ndarray, v_free: np.ndarray, dt: float, t: float
    ) -> np.ndarray:
        """The impulses of every row (see :meth:`_solve`) from the free velocity ``v_free``: of the contacts the free
        motion closes, then of those the others' impulses close too (solved again until none is added; a grown
        problem the solvers miss given up for the one before it), as the compiled step."""
        k = len(contacts.gaps)
        reach = jacobian @ v_free
        closed = contacts.gaps + dt * reach[: 3 * k : 3] <= TOUCH_GAP
        impulses = self._impulses(contacts, jacobian, mobility, reach, closed, dt, t)
        while True:
            grown = closed | (
                contacts.gaps + dt * (jacobian @ (v_free + mobility @ impulses))[: 3 * k : 3] <= TOUCH_GAP
            )
            if np.array_equal(grown, closed):
                return impulses
            try:
                impulses, closed = self._impulses(contacts, jacobian, mobility, reach, grown, dt, t), grown
            except ContactSolveError:
                return impulses

    def _impulses(
        self,
        contacts,
        jacobian: np.ndarray,
        mobility: np.ndarray,
        reach: np.ndarray,
        closed: np.ndarray,
        dt: float,
        t: float,
    ) -> np.ndarray:
        """The impulses of every row (see :meth:`_solve`) of the contacts ``closed``, zero off them: their problem
        with the normal biases (gap / dt, Newton's impact law)."""
        active = [int(i) for i in np.flatnonzero(closed)]
        if not active:
            return np.zeros(jacobian.shape[0])
        offset = reach.copy()
        for i in active:
            restitution, normal_velocity = self.dynamics.contacts[i].restitution, contacts.velocities[i, 0]
            bias = contacts.gaps[i] / dt
            if restitution > 0.0 and normal_velocity < 0.0:
                bias = min(bias, restitution * normal_velocity)
            offset[3 * i] += bias
        return self._solve(jacobian, mobility, offset, active, t)

    def _solve(
        self, jacobian: np.ndarray, mobility: np.ndarray, offset: np.ndarray, active: list[int], t: float
    ) -> np.ndarray:
        """The impulses of every row (3k (n, t1, t2) [N s], then the torsions' [N m s]), zero off ``active``: ADMM
        on the cones scaled to at most 1 (:mod:`~pinstab.bench.torsion_admm`'s with torsion rows), checked."""
        contacts = self.dynamics.contacts
        mus = [contacts[i].mu for i in active]
        places = torsion_rows([c.torsion for c in contacts])
        torsions = [contacts[i].torsion for i in active]
        spun = [places[i] for i in active if places[i] is not None]
        rows = np.array([3 * i + r for i in active for r in CONE_ROWS] + spun, dtype=int)
        delassus, g = jacobian[rows] @ mobility[:, rows], offset[rows]
        if spun:
            settings = self.solver.settings
            solution, _ = torsion_admm(
                delassus, g, mus, torsions, settings.absolute_feasibility_tol, settings.max_iterations
            )
        else:
            solution = self._cone_solve(delassus, g, mus)
        if not _residual_ratio(delassus, g, solution, mus, torsions) <= 1.0:
            names = [contacts[i].name for i in active]
            raise ContactSolveError(f"at t = {t:.9g} s the solvers missed the contact law", names, t)
        impulses = np.zeros(jacobian.shape[0])
        impulses[rows] = solution
        return impulses

    def _cone_solve(self, delassus: np.ndarray, g: np.ndarray, mus: list[float]) -> np.ndarray:
        """The impulses (t1, t2, n per contact) of a problem without torsion rows: Pinocchio's ADMM on the cones
        scaled to at most 1, then its PGS when ADMM's answer misses the contact law."""
        scales = np.array([s for mu in mus for s in (max(mu, 1.0), max(mu, 1.0), 1.0)])
        key = tuple(mus)
        if key not in self.cones:
            self.cones[key] = friction_cones([min(mu, 1.0) for mu in mus])
        scaled = scales[:, None] * delassus * scales
        operator = pin.DelassusOperatorDense(0.5 * (scaled + scaled.T))
        problem = (operator, scales, g, self.cones[key], delassus, mus)
        solution = self._rounds(self.solver.solver, self.solver.result, admm_settings(1e-12, CHECK_EVERY), *problem)
        if _residual_ratio(delassus, g, solution, mus) <= 1.0:
            return solution
        settings = pin.PGSSolverSettings()
        settings.solve_ncp = True
        for name in ("feasibility", "complementarity"):
            setattr(settings, f"absolute_{name}_tol", 1e-12)
            setattr(settings, f"relative_{name}_tol", 1e-12)
        pgs = pin.PGSConstraintSolver(len(g))
        fresh = pin.DelassusOperatorDense(0.5 * (scaled + scaled.T))  # PGS reads the damping ADMM left: none here
        return self._rounds(pgs, pin.PGSSolverResult(), settings, fresh, *problem[1:])

    def _rounds(self, solver, result, settings, operator, scales, g, cones, delassus, mus) -> np.ndarray:
        """The compiled solve's runs (cpp/cone_solve.cpp solve_in_rounds) of ``solver``, each from zero:
        :data:`CHECK_EVERY` iterations, half as many, twice as many and so on; the converged answer, else the best
        one once a run no longer shrinks the residual by :data:`ROUND_SETTLED` against the run of half its
        iterations (the first run against the half run)."""
        least, best, ratios = math.inf, None, {}
        for size, pair in _runs(
            min(CHECK_EVERY, self.solver.settings.max_iterations), self.solver.settings.max_iterations
        ):
            settings.max_iterations = size
            result.clearConstraintImpulseGuess()
            solver.solve(operator, scales * g, *cones, settings, result)
            solution = scales * result.retrieveConstraintImpulses()
            if result.converged:
                return solution
            found = _residual_ratio(delassus, g, solution, mus)
            ratios[size] = least if math.isnan(found) else found
            if best is None or ratios[size] < least:
                least, best = ratios[size], solution
            settled = pair is not None and least <= 1.0 and ratios[pair[0]] > ROUND_SETTLED * ratios[pair[1]]
            if settled or size == self.solver.settings.max_iterations:
                return best
        return best

    def _free_velocity(
        self,
        q: np.ndarray,
        v: np.ndarray,
        dt: float,
        force: np.ndarray,
        factor: tuple,
        at_start: np.ndarray,
        change: np.ndarray,
        v_free: np.ndarray,
    ) -> np.ndarray:
        """v_free [m/s, rad/s] with the velocity terms and the free flyers' turn at the midpoint of v and
        v_free + ``change`` (the impulses' velocity change), by fixed point from ``v_free`` (``at_start``: h at
        (q, v))."""
        model, data = self.system.model.model, self.system.model.scratch
        for _ in range(MIDPOINT_PASSES):
            middle = (v + v_free + change) / 2
            shift = pin.nonLinearEffects(model, data, q, middle) - at_start
            v_next = v + dt * (cho_solve(factor, force - shift) - self._turn(middle))
            moved = float(np.max(np.abs(v_next - v_free), initial=0.0))
            v_free = v_next
            if moved <= MIDPOINT_TOLERANCE * float(np.max(np.abs(v_free), initial=0.0)):
                return v_free
        raise Failure(f"the velocity terms at the step's midpoint did not settle in {MIDPOINT_PASSES} passes")

    def _turn(self, v: np.ndarray) -> np.ndarray:
        """-omega x v_lin in each free flyer's translation rows."""
        shift = np.zeros_like(v)
        for _, iv in self.free_flyers:
            shift[iv : iv + 3] = -np.cross(v[iv + 3 : iv + 6], v[iv : iv + 3])
        return shift

    def _integrate(self, q: np.ndarray, v: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """q (+) dt v with each free flyer moved by dt pdot; v with its v_lin in its joint frame at q+."""
        model = self.system.model.model
        q_next, v_next = pin.integrate(model, q, dt * v), v.copy()
        for iq, iv in self.free_flyers:
            rate = pin.Quaternion(q[iq + 3 : iq + 7]).toRotationMatrix() @ v[iv : iv + 3]
            q_next[iq : iq + 3] = q[iq : iq + 3] + dt * rate
            v_next[iv : iv + 3] = pin.Quaternion(q_next[iq + 3 : iq + 7]).toRotationMatrix().T @ rate
        return q_next, v_next


def _residual_ratio(
    delassus: np.ndarray, g: np.ndarray, solution: np.ndarray, mus: list[float], torsions: list[float] | None = None
) -> float:
    """An answer's :func:`~pinstab.solvers.ncp.ncp_residual` over the residual the check accepts (passes at <= 1)."""
    scale = max(float(np.max(np.abs(g))), float(np.max(np.abs(delassus @ solution))))
    return ncp_residual(delassus, g, solution, mus, torsions) / (CHECK_RTOL * scale)


def _runs(first: int, total: int) -> list[tuple[int, tuple[int, int] | None]]:
    """The rounds' run sizes up to ``total`` iterations, each with the (longer, shorter) pair of runs whose residuals
    tell, once it has run, whether the residual settled: ``first``, its half (against the first), then twice
    ``first`` (against the first), four times (against twice) and so on."""
    runs: list[tuple[int, tuple[int, int] | None]] = [(first, None)]
    if 1 < first < total:
        runs.append((first // 2, (first, first // 2)))
    size = first
    while size < total:
        runs.append((min(2 * size, total), (min(2 * size, total), size)))
        size = min(2 * size, total)
    return runs
