"""The stepping system: a :class:`~pinstab.model.ConstrainedModel` with a stabilizer and a KKT backend,
``(q, v, t) -> (a, lambda)`` (docs/mathematics.md eq. 3)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .constraints import ConstraintSet, ConstraintValues, FrameClosure, Violation
from .errors import ContactInfeasibleError, DivergenceError, PinstabError
from .kernels import Kernel
from .model import ConstrainedModel
from .paths.banded import BandedDynamics, BandedProjector, banded_obstacle
from .paths.core import CoreDynamics, CoreProjector, core_obstacle
from .paths.native import NATIVE_KINDS, NativeDynamics, NativeProjector, non_planar_closure, unsupported_constraint
from .paths.servo import ServoDynamics, servo_obstacle
from .projection import GeneralProjector, Projector
from .runinfo import SolverStatistics
from .scene import Scene
from .servo import RANK_TOLERANCE, ServoSolver
from .solvers import SOLVERS, KKTProblem, KKTSolution, KKTSolver
from .solvers.base import ACCEPTED_RESIDUAL
from .solvers.impacts import REST_SPEED
from .solvers.proxsuite_ import DIRECT_PIVOT
from .stabilizers import STABILIZERS, Stabilizer

DEFAULT_SOLVER = "proxsuite"
NATIVE_SOLVER = "pinocchio"  # the backend whose algorithm the native path runs
CORE_SOLVER = "proxsuite"  # the backend whose direct solve the core path repeats (and takes where rows are redundant)
NATIVE_MU = 1e-12  # proximal regularization of the native solve (the pinocchio backend's own option when named)
REDUNDANT_MU = 1e-8  # ... with redundant closure rows: relative to the largest eigenvalue of G M^-1 G^T
REDUNDANT_RANK_TOLERANCE = 1e-9  # singular values of G below this fraction of the largest: redundant rows


@dataclass
class Evaluation:
    """Dynamics at one state: accelerations [m/s^2, rad/s^2], multipliers, constraint values (None on
    the direct Pinocchio path, which does not form them), and with prescribed constraints the controls
    u [N m or N] that realize them (their rows' multipliers are then zero)."""

    acceleration: np.ndarray
    multipliers: np.ndarray
    values: ConstraintValues | None
    controls: np.ndarray | None = None


class OpenRows:
    """The unilateral rows of held constraints (a frictionless contact, a user's unilateral row) that have opened: left
    out of the dynamics while open (no force). Their acceleration-level row ``G a >= rhs`` would otherwise hold
    a point flying over its plane back, and the stabilization's terms (``-Kd g - Kp phi`` of a gap closing) push
    it across the gap, doing work: a spinning ball's body-fixed contact point, lifted by the spin and pushed back
    on its way down, gained 0.0085 J on its 0.0083 J.

    Decided at each step's start (stage 0, an accepted state): a held row opens where the solve leaves it without
    force and slack (both beyond the solve's accuracy, :data:`~pinstab.solvers.base.ACCEPTED_RESIDUAL` relative:
    :meth:`release`); an open row whose gap is back at 0 is held again when its point arrives
    slower than :data:`~pinstab.solvers.impacts.REST_SPEED`, and faster it is an impact, which held rows do not
    model (their stabilization would catch the point as a spring and damper across the plane): the run stops with
    :class:`~pinstab.errors.ContactInfeasibleError`. The decisions are kept by time, so a step taken again from an
    earlier state (a replayed or shorter step) starts from the rows open then.

    Attributes:
        rows: the rows open now (mask over the stack's rows).
    """

    def __init__(self, stack: ConstraintSet) -> None:
        self.stack = stack
        self.rows = np.zeros(stack.rows, dtype=bool)
        self._decided: list[tuple[float, np.ndarray]] = []  # (t [s], the rows open from t on), on each change
        self._starts: list[tuple[float, np.ndarray]] = []  # the last two step starts' (t [s], velocity residuals)

    def begin(self, values: ConstraintValues, t: float) -> np.ndarray:
        """The rows open at a step's start, at time t [s] with the constraint ``values``: those open before t
        that have not come back to their plane (gap <= 0).

        Raises:
            ContactInfeasibleError: an open row back at its plane whose point arrives faster than REST_SPEED, at
                this state or at the previous step's start (a post-step projection, ``projection`` and ``post``,
                puts the point back on its plane at rest: the impact without its law).
        """
        while self._decided and self._decided[-1][0] >= t:
            self._decided.pop()
        before = self._decided[-1][1] if self._decided else np.zeros_like(self.rows)
        arriving = values.velocity_residual
        self._starts = [start for start in self._starts if start[0] < t]
        if self._starts:
            arriving = np.minimum(arriving, self._starts[-1][1])
        self._starts = [*self._starts[-1:], (t, arriving.copy())]
        back = before & (values.phi <= 0.0)
        impacts = back & (arriving < -REST_SPEED)
        if impacts.any():
            self._refuse(impacts, arriving, t)
        self._decide(t, before & ~back)
        return self.rows

    def within(self, values: ConstraintValues, t: float) -> np.ndarray:
        """The rows open at a stage of a step (at time t [s] with the constraint ``values``): those open at its start.

        Raises:
            ContactInfeasibleError: an open row's point across its plane (gap <= 0) and arriving faster than
                REST_SPEED at the stage: the step crosses the plane, an impact inside it.
        """
        impacts = self.rows & (values.phi <= 0.0) & (values.velocity_residual < -REST_SPEED)
        if impacts.any():
            self._refuse(impacts, values.velocity_residual, t)
        return self.rows

    def release(self, problem: KKTProblem, solution: KKTSolution, t: float) -> None:
        """Open the held unilateral rows that the solve of a step's start (at t [s]) left without force and slack:
        the multiplier within ACCEPTED_RESIDUAL of the forces in play (the largest multiplier and applied force) and
        ``G a - rhs`` above ACCEPTED_RESIDUAL of the row's accelerations (its free one ``G M^-1 f``, ``G a`` and
        ``rhs``). A row that holds carries a force, or is slack by rounding (ProxQP leaves 1e-8 of them)."""
        jacobian, forces = problem.jacobian, solution.multipliers
        scale = float(np.max(np.abs(forces), initial=0.0)) + float(np.max(np.abs(problem.free_force), initial=0.0))
        unloaded = self.stack.layout.unilateral & ~self.rows & (forces <= ACCEPTED_RESIDUAL * scale)
        if not unloaded.any():  # every held row carries a force: no mass-matrix solve for the slack test
            return
        reached = jacobian @ solution.acceleration
        free = jacobian @ np.linalg.solve(problem.mass_matrix, problem.free_force)
        size = np.abs(free) + np.abs(reached) + np.abs(problem.rhs)
        released = unloaded & (reached - problem.rhs > ACCEPTED_RESIDUAL * size)
        if released.any():
            self._decide(t, self.rows | released)

    def _decide(self, t: float, rows: np.ndarray) -> None:
        """Make ``rows`` the open ones from t [s] on (kept when they differ from those in effect before)."""
        if not np.array_equal(rows, self._decided[-1][1] if self._decided else np.zeros_like(rows)):
            self._decided.append((t, rows))
        self.rows = rows

    def _refuse(self, impacts: np.ndarray, arriving: np.ndarray, t: float) -> None:
        stack = self.stack
        names = list(dict.fromkeys(stack.layout.names[row] for row in np.flatnonzero(impacts)))
        speeds = [-float(np.min(arriving[stack.slices[name]])) for name in names]
        described = ", ".join(f"{name} at {speed:.6g} m/s" for name, speed in zip(names, speeds, strict=True))
        raise ContactInfeasibleError(
            f"held contacts close again at t = {t:.6g} s: {described} (the speed along the normal; at most "
            f"{REST_SPEED:g} m/s is at rest). A contact that opened and closes again has an impact, which held rows "
            "(no impacts) do not model; run it with --contacts event (simulate(contacts='event')), whose impacts "
            "follow Newton's law",
            names,
            t,
        )


class ConstrainedSystem:
    """docs/mathematics.md eq. (3): ``M a + h = tau + G^T lambda``, ``G a = -gamma0 + gamma_stab``.

    Args:
        model: the constrained model.
        stabilizer: provides gamma_stab and post-step corrections.
        solver: the KKT backend of the general path.
        native_obstacle: why the native path may not be taken whatever the scene (a solver was named
            that is not Pinocchio's), or None.
        banded: take the banded path where it pays (False: Pinocchio's solve on the native path, the
            ``pinocchio`` solver named).

    Attributes:
        path: ``native`` (Pinocchio's ``constraintDynamics`` with the stabilizer's Baumgarte gains in
            its corrector, :mod:`pinstab.paths.native`), ``banded`` (the same equations solved by a banded LU
            at a cost linear in the chain's length, :mod:`pinstab.paths.banded`; refined near a singular
            configuration, Pinocchio's solve at one), ``servo`` (prescribed joint relations realized by the controls,
            solved compiled, :mod:`pinstab.paths.servo`), ``core`` (the standard rows and compiled force elements,
            solved compiled, :mod:`pinstab.paths.core`) or ``general`` (pinstab's kinematics, the stabilizer's term
            and the KKT backend); chosen by :meth:`bind`.
        path_reason: why the general path was taken, or why the banded, servo or core one ("" on the native path).
        acceleration: ``acceleration(q, v, t, stage) -> a`` on the chosen path [m/s^2, rad/s^2].
        native: Pinocchio's dynamics on the native path, else None.
        compiled_path: the compiled servo solve on the servo path, the core evaluation on the core path, else None.
        projector: the projections of post-step corrections on the chosen path.
        opened: the unilateral rows that opened (:class:`OpenRows`), None without unilateral rows.
    """

    def __init__(
        self,
        model: ConstrainedModel,
        stabilizer: Stabilizer,
        solver: KKTSolver,
        native_obstacle: str | None = None,
        banded: bool = True,
    ) -> None:
        self.model = model
        self.stabilizer = stabilizer
        self.solver = solver
        self.native: NativeDynamics | None = None
        self.banded: BandedDynamics | None = None
        self.compiled_path: ServoDynamics | CoreDynamics | None = None
        self._banded_allowed = banded
        self._banded_solves = 0
        self._compiled_solves = 0
        self.projector: Projector = GeneralProjector(model)
        self.path = "general"
        self.path_reason = "not bound to a step yet"
        self.acceleration: Callable[[np.ndarray, np.ndarray, float, int], np.ndarray] = self._general_acceleration
        self._named_solver = native_obstacle
        self._checking = True  # check every native solve (until one passes)
        self._native_solves = 0
        self._audit = SolverStatistics()
        constraints = model.constraints
        self.opened = OpenRows(constraints) if constraints.layout.unilateral.any() else None
        self.servo = (
            ServoSolver(constraints.prescribed_mask, constraints.layout.names, model.scene.actuation)
            if constraints.prescribed_mask.any()
            else None
        )

    # -- choosing the path -------------------------------------------------------------------------
    def bind(self, step: float, integrator: str, q: np.ndarray, varying: bool = False) -> None:
        """Bind the stabilizer to the step [s] (the first, where ``varying``: error control), the integrator and the
        start configuration, and take the native path when the scene, the method and the solver allow it."""
        self.stabilizer.bind(self.model, step, integrator, q, varying)
        self.compiled_path = self.banded = None  # a previous bind's
        reason = self.native_obstacle(q)
        if reason is not None:
            self.path, self.path_reason, self.native = "general", reason, None
            self.acceleration = self._general_acceleration
            self.projector = GeneralProjector(self.model)
            if self._named_solver is None and self.servo is not None:
                self._bind_servo()
            elif self._named_solver is None:
                self._bind_core()
            return
        gains = self.stabilizer.baumgarte_gains()
        native = self.solver.native
        if native is None:
            closures = [c for c in self.model.constraints.constraints if isinstance(c, FrameClosure)]
            start = q.copy()  # mu from the start, when Pinocchio's solve is first needed (the banded path: rarely)
            native = NativeDynamics(
                self.model.model, closures, *gains, mu=lambda: self.native_mu(start), data=self.model.scratch
            )
        native.set_gains(*gains)
        native.set_forces(self.model.forces, self.model.constraints.slices)
        self.native = native
        if self.stabilizer.corrects:
            self.projector = NativeProjector(self.model.model, native.closures)
        self.path, self.path_reason = "native", ""
        self.acceleration = self._native_acceleration
        self._checking = True
        self.banded = self._banded(native)
        if self.banded is not None:
            self.path, self.acceleration = "banded", self._banded_acceleration
            self.projector = BandedProjector(self.banded, GeneralProjector(self.model))
            self.path_reason = (
                f"{len(native.closures)} point closures: KKT system of {self.banded.size} unknowns with a band of "
                f"{self.banded.band}, solved at linear cost (refined near a singular configuration, Pinocchio's solve "
                "at one)"
            )

    def _bind_servo(self) -> None:
        """Take the servo path when the scene's constraints, the method and the scene's gravity allow it; else say
        why in :attr:`path_reason`."""
        model = self.model
        reason = servo_obstacle(model.constraints.constraints, model.scene.actuation)
        if reason is None:
            reason = self._compiled_form_obstacle("the compiled servo solve")
        if reason is not None:
            self.path_reason = reason
            return
        relations = list(model.constraints.constraints)
        gains = self.stabilizer.baumgarte_gains()
        self.compiled_path = ServoDynamics(model.model, relations, model.scene.actuation, *gains, RANK_TOLERANCE)
        self.path, self.acceleration = "servo", self._compiled_acceleration
        self.path_reason = (
            f"{len(relations)} prescribed joint relation(s) realized by {model.scene.actuation.count} control(s): "
            "M, h and the decoupling matrix S M^-1 B solved compiled (the general solve where it loses rank or a "
            "control meets its bound)"
        )

    def _bind_core(self) -> None:
        """Take the core path when every constraint is an equality block and not prescribed, the method's term has
        the core's form (:meth:`~pinstab.stabilizers.base.Stabilizer.core_term`) and the KKT backend's solve is the
        direct one the core repeats; else say why in :attr:`path_reason`. Blocks without compiled rows and force
        elements without a compiled form are evaluated in Python at each evaluation (the reason names them)."""
        model = self.model
        constraints = model.constraints
        reason = core_obstacle(constraints.constraints)
        if reason is None:
            reason = self._compiled_form_obstacle("the core evaluation", core=True)
        if reason is None and not (self.solver.name == CORE_SOLVER and self.solver.options.direct):
            reason = f"solver {self.solver.name} solves every evaluation by its own method (not Cholesky factors)"
        if reason is not None:
            self.path_reason = reason
            return
        term = self.stabilizer.core_term()
        if term.inertial is not None and any(c.compiled_rows() is None for c in constraints.constraints):
            self.path_reason = (
                f"method {self.stabilizer.name}'s inertial term reads G at a second configuration, which Python rows "
                "do not give the core"
            )
            return
        self.compiled_path = CoreDynamics(model, term, DIRECT_PIVOT, ACCEPTED_RESIDUAL)
        self.path, self.acceleration = "core", self._compiled_acceleration
        if self.stabilizer.corrects:  # its rows projected in C++ too
            self.projector = CoreProjector(self.compiled_path)
        in_python = self.compiled_path.in_python()
        self.path_reason = (
            f"{len(constraints.constraints)} constraint block(s) of {constraints.rows} rows, {len(model.forces)} force "
            "element(s): kinematics, rows, forces and the KKT solve compiled (Cholesky factors, a pseudo-inverse where "
            "rows are redundant or nearly so; the general solve where it misses the rows, a contact's force leaves its "
            f"limits or a hold's its cones){'; ' + in_python if in_python else ''}"
        )

    def _banded(self, native: NativeDynamics) -> BandedDynamics | None:
        """The banded solve of the native path's closures when it pays (see :func:`banded_obstacle`):
        allowed, and a method without post-step corrections (those run on Pinocchio's factorization)."""
        if not self._banded_allowed or self.stabilizer.corrects or banded_obstacle(native.closures, 0) is not None:
            return None
        banded = BandedDynamics(self.model.model, native.closures, native.kp, native.kd, data=self.model.scratch)
        return banded if banded_obstacle(native.closures, banded.size, banded.band) is None else None

    def native_mu(self, q: np.ndarray) -> float:
        """The proximal regularization of the native solve from configuration q: :data:`NATIVE_MU`, or
        with redundant closure rows (G rank-deficient at q, e.g. an overconstrained loop)
        :data:`REDUNDANT_MU` times the largest eigenvalue of the Delassus matrix G M^-1 G^T. With
        redundant rows that matrix is singular, and Pinocchio factors G M^-1 G^T + mu I: a mu of 1e-12
        amplifies rounding to 1e-10 relative errors in the accelerations (10^-8 of the energy in 10 s on
        ``bricard``); the larger mu keeps them at rounding while the proximal loop still converges.
        """
        model = self.model
        jacobian = model.constraint_values(q, np.zeros(model.nv), 0.0, model.scratch_kinematics).jacobian
        singular = np.linalg.svd(jacobian, compute_uv=False)
        if not singular.size or np.sum(singular > REDUNDANT_RANK_TOLERANCE * singular[0]) == jacobian.shape[0]:
            return NATIVE_MU
        delassus = jacobian @ np.linalg.solve(self.model.mass_matrix(q), jacobian.T)
        return max(NATIVE_MU, REDUNDANT_MU * float(np.linalg.eigvalsh(delassus)[-1]))

    def _compiled_form_obstacle(self, solve: str, core: bool = False) -> str | None:
        """Why the scene's gravity or the method keeps a compiled ``solve`` (named in the reason) off: gravity that
        tilts in time (unless the solve is the ``core``'s, which tilts it), a stabilization term not of Baumgarte's
        form (the core's: not of its form, :meth:`~pinstab.stabilizers.base.Stabilizer.core_term`); or None."""
        if self.model.scene.tilt is not None and not core:
            return f"gravity tilts in time ([tilt]); {solve} takes the model's one gravity"
        if core and self.stabilizer.core_term() is None:
            return f"method {self.stabilizer.name}'s term is not of the core's form -K (G v + g_t) - S phi"
        if not core and self.stabilizer.baumgarte_gains() is None:
            return f"method {self.stabilizer.name}'s term is not Baumgarte's -Kp phi - Kd G v at every stage"
        return None

    def native_obstacle(self, q: np.ndarray) -> str | None:
        """Why the native path cannot run this system from configuration q, or None."""
        if self._named_solver is not None:
            return self._named_solver
        constraints = self.model.constraints.constraints
        reason = unsupported_constraint(constraints, NATIVE_KINDS)
        if reason is not None:
            return reason
        reason = self._compiled_form_obstacle("Pinocchio's solve")
        if reason is not None:
            return reason
        closures = [c for c in constraints if isinstance(c, FrameClosure)]
        name = non_planar_closure(self.model.model, self.model.scratch, closures, q)
        if name is not None:
            return f"planar-point closure {name!r} is not on a planar mechanism"
        return None

    def compiled_kernel(self) -> Kernel | None:
        """The compiled evaluation of this path for the compiled step loop (:mod:`pinstab.integration.compiled`):
        the banded solve's, or Pinocchio's on the native path once its solves pass their check; None while they
        are checked one by one, or on the general path."""
        if self.banded is not None:
            return self.banded.kernel
        if self.compiled_path is not None:
            return self.compiled_path.kernel
        if self.native is None or self._checking:
            return None
        return self.native.kernel()

    def count_compiled(self, evaluations: int) -> None:
        """Count ``evaluations`` solves made by the compiled loop on this path."""
        if self.compiled_path is not None:
            self._compiled_solves += evaluations
        elif self.banded is not None:
            self._banded_solves += evaluations
        else:
            self._native_solves += evaluations

    @property
    def conditioning(self) -> Callable[[np.ndarray, int], float] | None:
        """``(q, r) -> sigma_r / sigma_1`` of the constraint Jacobian without a dense SVD (the banded path's),
        or None."""
        return None if self.banded is None else self.banded.relative_singular_value

    @property
    def constraint_jacobian(self) -> Callable[[np.ndarray], np.ndarray] | None:
        """``q -> G`` (rows x nv) without pinstab's Python pass over the rows (the banded path's compiled one), or
        None."""
        return None if self.banded is None else self.banded.jacobian

    # -- evaluations ---------------------------------------------------------------------------------
    def _native_solve(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """Pinocchio's accelerations at (q, v, t) under the scene's forces, unchecked."""
        return self.native.acceleration(q, v, self.model.applied_force_at(q, v, t))

    def _banded_acceleration(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        acceleration = self.banded.acceleration(q, v, self.model.applied_force_at(q, v, t))
        if self.banded.singular:
            self._audit.fallbacks += 1
            return self._native_acceleration(q, v, t, stage)
        self._banded_solves += 1
        return acceleration

    def _compiled_acceleration(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        path = self.compiled_path
        acceleration = path.acceleration(q, v, path.force(self.model, q, v, t), t, stage)
        if path.unusable:  # the general solve says why (a servo: from the kernel's last sign) or solves it otherwise
            self._audit.fallbacks += 1
            if self.servo is not None:
                self.servo.follow(path.last_sign)
            if stage > 0 and isinstance(path, CoreDynamics) and path.held:
                held = path.held_term()  # None: the general path computed this step's at stage 0, and holds it
                if held is not None:
                    self.stabilizer.hold_term(held)
            return self._general_acceleration(q, v, t, stage)
        self._compiled_solves += 1
        return acceleration

    def _native_acceleration(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        model = self.model
        if model.forces:
            acceleration = self._native_solve(q, v, t)
        else:  # _native_solve without its calls: the four-bar's step costs ~5 us, a call ~0.1 us
            acceleration = self.native.acceleration(q, v, model.no_force)
        self._native_solves += 1
        if self._checking:
            return self._checked(q, v, t, stage, acceleration)
        return acceleration

    def _checked(self, q: np.ndarray, v: np.ndarray, t: float, stage: int, acceleration: np.ndarray) -> np.ndarray:
        """The native solve if it passes :meth:`NativeDynamics.residual`, else the general path's."""
        residual = self.native.residual(v, acceleration)
        if residual <= ACCEPTED_RESIDUAL:
            self._audit.record("native checked", 0, residual, math.nan)
            self._checking = False
            return acceleration
        self._audit.fallbacks += 1
        return self._general_acceleration(q, v, t, stage)

    def audit(self, q: np.ndarray, v: np.ndarray, t: float) -> None:
        """On the native path, check a solve at (q, v, t) from scratch; when it fails (near a singular
        configuration) every native solve is checked, a failed one solved the general way, until one
        passes. The stepping loop calls this periodically."""
        if self.native is None or self.banded is not None:  # the banded LU checks every solve (its pivots)
            return
        residual = self.native.residual(v, self._native_solve(q, v, t))
        self._checking = not residual <= ACCEPTED_RESIDUAL
        if not self._checking:
            self._audit.record("native checked", 0, residual, math.nan)

    def _general_acceleration(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        return self.dynamics(q, v, t, stage).acceleration

    def violation(self, q: np.ndarray, v: np.ndarray, t: float) -> Violation:
        """The constraint violation at (q, v, t) [m or rad, m/s or rad/s]: the model's, computed by the banded
        kernel on the banded path (its closures are all the constraints there; no Python pass over them)."""
        if self.banded is not None:
            return self.banded.violation(q, v)
        return self.model.violation(q, v, t)

    def multipliers(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The constraint multipliers at (q, v, t) [N, N m]: Pinocchio's on the native path when its solve
        passes the check (the banded solve's on the banded path, the core kernel's on the core path: the least-norm
        ones of redundant rows), else the general path's."""
        path = self.compiled_path
        if isinstance(path, CoreDynamics):
            path.acceleration(q, v, path.force(self.model, q, v, t), t)
            if not path.unusable:
                return path.kernel.multipliers()
        if self.banded is not None:
            self._banded_acceleration(q, v, t)
            if not self.banded.singular:
                return self.banded.multipliers()
        if self.native is not None and self.native.residual(v, self._native_solve(q, v, t)) <= ACCEPTED_RESIDUAL:
            return self.native.multipliers()
        return self.dynamics(q, v, t).multipliers

    @property
    def statistics(self) -> SolverStatistics:
        """The run's solves: the KKT backend's, and on the native path Pinocchio's solves (status
        ``native``), the checked ones and the fallbacks; on the banded path its solves (status ``banded``),
        those of them refined near a singular configuration (status ``banded refined``), a singular one solved by
        Pinocchio counted as a fallback; on the servo path its compiled solves (status ``servo``), on the core path its
        kernel's by how it solved them (``core cholesky``, ``core pseudo-inverse``, and those not used), those the
        general solve took counted as fallbacks."""
        merged = dataclasses.replace(self.solver.statistics, status_counts=dict(self.solver.statistics.status_counts))
        if self.compiled_path is not None:
            merged.solves += self._compiled_solves
            path = self.compiled_path
            if isinstance(path, CoreDynamics):  # by how its kernel solved them
                merged.status_counts.update(path.status_counts())
            else:
                merged.status_counts[path.status] = self._compiled_solves
            merged.worst_primal_residual = max(merged.worst_primal_residual, self.compiled_path.worst_residual)
            merged.fallbacks += self._audit.fallbacks
        if self.native is None:
            return merged
        audit = self._audit
        merged.solves += self._native_solves
        merged.status_counts["native"] = self._native_solves
        merged.status_counts["native checked"] = audit.status_counts.get("native checked", 0)
        if self.banded is not None:
            merged.solves += self._banded_solves
            merged.status_counts["banded"] = self._banded_solves
            merged.status_counts["banded refined"] = self.banded.kernel.refinements
        merged.worst_primal_residual = max(merged.worst_primal_residual, audit.worst_primal_residual)
        merged.fallbacks += audit.fallbacks
        return merged

    def dynamics(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> Evaluation:
        """Accelerations and multipliers at (q, v, t) on the general path; ``stage`` is the integrator's
        stage index.

        Raises:
            DivergenceError: the state (or an integrator stage) is not finite.
        """
        if not (np.isfinite(q).all() and np.isfinite(v).all()):
            raise DivergenceError(f"non-finite state reached at t = {t:.6g} s", t, q, v)
        model = self.model
        terms = model.dynamics_terms(q, v, t)
        values = terms.values
        rhs = -values.drift
        gamma = self.stabilizer.stabilization_term(model, q, v, t, values, stage)
        if gamma is not None:
            rhs = rhs + gamma
        jacobian, layout, opened = values.jacobian, model.constraints.layout, self.opened
        open_rows = None if opened is None else (opened.begin(values, t) if stage == 0 else opened.within(values, t))
        if open_rows is not None and open_rows.any():  # zero rows, 0 >= 0: their multipliers are 0
            jacobian, rhs = np.where(open_rows[:, None], 0.0, jacobian), np.where(open_rows, 0.0, rhs)
        problem = KKTProblem(q, v, t, terms.tau, terms.mass_matrix, terms.tau - terms.bias, jacobian, rhs, layout)
        if self.servo is not None:
            return self._servo_dynamics(problem, values)
        solution = self.solver.solve(problem)
        if opened is not None and stage == 0:
            opened.release(problem, solution, t)
        if not np.isfinite(solution.acceleration).all():
            raise DivergenceError(f"non-finite acceleration from solver {self.solver.name} at t = {t:.6g} s", t, q, v)
        if model.constraints.force_limited:
            model.constraints.check_forces(solution.multipliers, t)
        return Evaluation(solution.acceleration, solution.multipliers, values)

    def _servo_dynamics(self, problem: KKTProblem, values: ConstraintValues) -> Evaluation:
        """The dynamics with prescribed rows: accelerations, reactions and the controls (:mod:`pinstab.servo`)."""
        state = (problem.t, problem.q, problem.v)
        solution = self.servo.solve(problem.mass_matrix, problem.free_force, problem.jacobian, problem.rhs, state)
        if not np.isfinite(solution.acceleration).all():
            raise DivergenceError(f"non-finite acceleration at t = {problem.t:.6g} s", problem.t, problem.q, problem.v)
        if self.model.constraints.force_limited:
            self.model.constraints.check_forces(solution.multipliers, problem.t)
        return Evaluation(solution.acceleration, solution.multipliers, values, solution.controls)


def build_system(
    scene: Scene | ConstrainedModel,
    method: str = "baumgarte",
    solver: str | None = None,
    solver_options: Mapping[str, Any] | Any | None = None,
    **method_options: Any,
) -> ConstrainedSystem:
    """A :class:`ConstrainedSystem` for the named method and solver.

    Args:
        scene: a scene, or its constrained model.
        method: a registered stabilization method.
        solver: a registered KKT backend; None: the native path where the scene allows it (see
            :meth:`ConstrainedSystem.bind`; the banded path for a chain of point closures, where it
            pays), the method's own backend or ``proxsuite`` elsewhere. Naming ``pinocchio`` keeps
            Pinocchio's solve (the native path, the reference of the banded one); naming ``proxsuite``
            or ``dense`` keeps every evaluation on the general path.
        solver_options: the backend's options.
        method_options: the method's options (e.g. ``kp``, ``kd``).

    ``system.bind(step, integrator, q0)`` chooses the path (and gives step-dependent gains, e.g.
    ``mukharlyamov``'s, their values); :func:`~pinstab.simulate.simulate` does it.
    """
    model = scene if isinstance(scene, ConstrainedModel) else ConstrainedModel(scene)
    stabilizer = STABILIZERS.build(method, options=method_options)
    name = solver or stabilizer.required_solver or DEFAULT_SOLVER
    if stabilizer.required_solver is not None and name != stabilizer.required_solver:
        raise PinstabError(f"method {method!r} runs on solver {stabilizer.required_solver!r}, not {name!r}")
    backend = SOLVERS.build(name, model, stabilizer.baumgarte_gains(), options=solver_options)
    obstacle = None if solver in (None, NATIVE_SOLVER) else f"solver {solver!r} was named"
    return ConstrainedSystem(model, stabilizer, backend, obstacle, banded=solver is None)
