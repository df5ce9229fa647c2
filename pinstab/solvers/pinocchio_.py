"""``pinocchio``: Pinocchio's own ``constraintDynamics`` (sparse constrained Cholesky + proximal loop)
as a KKT backend of the general path.

It fits scenes whose constraints are point and planar-point closures (:mod:`pinstab.paths.native`); its
stabilization term can only be Pinocchio's Baumgarte corrector (scalar Kp, Kd). Every solve is
checked against pinstab's own rows: when ``|G a - rhs|`` exceeds
:data:`~pinstab.solvers.base.ACCEPTED_RESIDUAL` (relative to the size of the terms) the same problem
is solved again by ProxQP and the fallback is counted.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..constraints import FrameClosure
from ..errors import SolverError
from ..paths.native import NativeDynamics, non_planar_closure, unsupported_constraint
from .base import ACCEPTED_RESIDUAL, SOLVERS, KKTProblem, KKTSolution, KKTSolver, check_row_kinds, primal_residual
from .proxsuite_ import ProxsuiteSolver

if TYPE_CHECKING:
    from ..model import ConstrainedModel


class PinocchioSolver(KKTSolver):
    """Pinocchio ``constraintDynamics`` as a KKT backend.

    Args:
        native: Pinocchio's dynamics of the scene's closures, with the corrector's gains.
    """

    name = "pinocchio"

    def __init__(self, native: NativeDynamics) -> None:
        super().__init__()
        self.native = native
        self._checked_planar = False
        self._fallback = ProxsuiteSolver()

    def solve(self, problem: KKTProblem) -> KKTSolution:
        native = self.native
        if not self._checked_planar:
            name = non_planar_closure(native.model, native.data, native.closures, problem.q)
            if name is not None:
                raise SolverError(
                    f"solver pinocchio: planar-point closure {name!r} is not on a planar mechanism (its "
                    "out-of-plane motion is not blocked by the joints), so it has no Pinocchio equivalent. "
                    "Use solver 'proxsuite' or 'dense'."
                )
            self._checked_planar = True
        acceleration = np.array(native.acceleration(problem.q, problem.v, problem.tau))
        residual_force = problem.mass_matrix @ acceleration - problem.free_force
        multipliers = np.linalg.lstsq(problem.jacobian.T, residual_force, rcond=1e-12)[0]
        primal = primal_residual(problem, acceleration)
        if np.all(np.isfinite(acceleration)) and not primal <= ACCEPTED_RESIDUAL:
            return self.fall_back(problem)
        # the multipliers are the least-squares ones of M a - f = G^T lambda: not measured again
        iterations = int(native.settings.iter)
        return self.record(KKTSolution(acceleration, multipliers, "solved", iterations, primal, math.nan))

    def fall_back(self, problem: KKTProblem) -> KKTSolution:
        """Solve with ProxQP (counted as a fallback; its statistics join this backend's)."""
        self.statistics.fallbacks += 1
        solution = self._fallback.solve(problem)
        return self.record(dataclasses.replace(solution, status=f"fallback {solution.status}"))


@dataclass(frozen=True)
class PinocchioOptions:
    """Options of the ``pinocchio`` backend."""

    mu: float = field(
        default=1e-12,
        metadata={"flag": "--pinocchio-mu", "help": "proximal regularization of constraintDynamics (default 1e-12)"},
    )

    def __post_init__(self) -> None:
        if not (isinstance(self.mu, float | int) and 0 <= self.mu < 1):
            raise ValueError(f"mu must be in [0, 1), got {self.mu!r}")


@SOLVERS.register(
    "pinocchio",
    options=PinocchioOptions,
    summary="Pinocchio's constraintDynamics and its corrector",
    capabilities=PinocchioSolver.row_kinds,
)
def make_pinocchio(
    model: ConstrainedModel, corrector_gains: tuple[float, float] | None, options: PinocchioOptions
) -> PinocchioSolver:
    """Pinocchio's backend; it applies the stabilizer's Baumgarte gains in its own corrector.

    Raises:
        SolverError: the stabilizer's term is not of Baumgarte form, or a row is not an equality.
    """
    if corrector_gains is None:
        raise SolverError(
            "solver 'pinocchio' applies only its own Baumgarte corrector, not this method's stabilization term; "
            "use solver 'proxsuite' or 'dense'"
        )
    check_row_kinds(PinocchioSolver, model)
    constraints = model.constraints.constraints
    reason = unsupported_constraint(constraints)
    if reason is not None:
        raise SolverError(f"solver pinocchio: {reason}. Use solver 'proxsuite' or 'dense'.")
    closures = [c for c in constraints if isinstance(c, FrameClosure)]
    return PinocchioSolver(NativeDynamics(model.model, closures, *corrector_gains, mu=options.mu, data=model.scratch))
