"""The constrained-dynamics problem handed to a KKT backend, what comes back (docs/mathematics.md eq. 4-5), how
a solve is judged, and the registry of backends."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .. import kernels
from ..constraints import RowKind, RowLayout
from ..errors import SolverError, choices
from ..registry import Registry
from ..runinfo import SolverStatistics

if TYPE_CHECKING:
    from ..model import ConstrainedModel
    from ..paths.native import NativeDynamics

# a solve is accepted when its residuals, relative to the size of the terms they balance, are below
# this, whatever status flag the backend raised (a singular configuration can make ProxQP report
# infeasibility with residuals at round-off)
ACCEPTED_RESIDUAL = 1e-8


@dataclass
class KKTProblem:
    """``M a = f + G^T lambda`` with ``G a = rhs`` on equality and cone rows, ``G a >= rhs`` on
    unilateral rows, lambda >= 0 on unilateral rows and inside the friction cone on cone rows.

    Attributes:
        q, v: state (some backends recompute the dynamics themselves). t: time [s], for messages.
        tau: applied generalized forces (force elements) [N, N m].
        mass_matrix: M [kg, kg m^2].
        free_force: f = tau - h [N, N m].
        jacobian: G (s x nv).
        rhs: -gamma0 + gamma_stab [m/s^2, rad/s^2].
        layout: row names, unilateral rows and cone triples.
    """

    q: np.ndarray
    v: np.ndarray
    t: float
    tau: np.ndarray
    mass_matrix: np.ndarray
    free_force: np.ndarray
    jacobian: np.ndarray
    rhs: np.ndarray
    layout: RowLayout


@dataclass
class KKTSolution:
    """A solve's answer and how good it is.

    Attributes:
        acceleration: [m/s^2, rad/s^2] (nv,). multipliers: (s,) [N, N m].
        status: the backend's word for the outcome. iterations: the backend's iterations.
        primal_residual: ``|G a - rhs|`` relative to its terms. dual_residual: ``|M a - f - G^T lambda|``
        relative to its terms; NaN where the backend does not measure it (exact by construction).
    """

    acceleration: np.ndarray
    multipliers: np.ndarray
    status: str = "solved"
    iterations: int = 0
    primal_residual: float = 0.0
    dual_residual: float = 0.0


def primal_residual(problem: KKTProblem, acceleration: np.ndarray) -> float:
    """How far ``G a = rhs`` is missed, relative [-]: ``|G a - rhs| / (|rhs| + |G|_F (|a| + |f| / min
    diag M))`` in the Euclidean norm, on the rows that are equalities at the acceleration level (a
    unilateral row counts only when violated). The accelerations the forces alone would cause set the
    scale too, so that a mechanism at rest (a ~ 0, rhs ~ 0) is not judged on rounding alone. The compiled
    rule (``cpp/core_kernel.cpp``), which the core evaluation applies too."""
    return kernels.primal_residual(
        problem.jacobian,
        acceleration,
        problem.rhs,
        problem.free_force,
        np.diagonal(problem.mass_matrix),
        problem.layout.unilateral,
    )


def residuals(problem: KKTProblem, acceleration: np.ndarray, multipliers: np.ndarray) -> tuple[float, float]:
    """(primal, dual) relative residuals of a candidate answer [-]: :func:`primal_residual`, and
    ``|M a - f - G^T lambda| / (|f| + |M|_F |a| + |G|_F |lambda|)`` (Euclidean norms)."""
    jac, mass, force = problem.jacobian, problem.mass_matrix, problem.free_force
    flat_jac, flat_mass = jac.ravel(), mass.ravel()
    unbalanced = mass @ acceleration - force - jac.T @ multipliers
    scale = (
        math.sqrt(float(force @ force))
        + math.sqrt(float(flat_mass @ flat_mass)) * math.sqrt(float(acceleration @ acceleration))
        + math.sqrt(float(flat_jac @ flat_jac)) * math.sqrt(float(multipliers @ multipliers))
    )
    return primal_residual(problem, acceleration), _ratio(unbalanced, scale)


def _ratio(residual: np.ndarray, scale: float) -> float:
    size = math.sqrt(float(residual @ residual))
    if size == 0.0:
        return 0.0
    return size / scale if scale > 0 else math.inf


class KKTSolver(ABC):
    """A backend that solves :class:`KKTProblem`.

    Attributes:
        name: the registered name.
        row_kinds: the row kinds it solves (a problem with others is refused when the solver is built).
        native: the backend's Pinocchio dynamics when it runs Pinocchio's algorithm (the native path
            then shares it), else None.
        statistics: counts and worst residuals of its solves.
    """

    name: str = ""
    row_kinds: frozenset[RowKind] = frozenset({RowKind.EQUALITY})
    native: NativeDynamics | None = None

    def __init__(self) -> None:
        self.statistics = SolverStatistics()

    @abstractmethod
    def solve(self, problem: KKTProblem) -> KKTSolution:
        """Solve one KKT system; raise :class:`~pinstab.errors.SolverError` on failure."""

    def record(self, solution: KKTSolution) -> KKTSolution:
        """Count a solve in :attr:`statistics` and return it."""
        self.statistics.record(solution.status, solution.iterations, solution.primal_residual, solution.dual_residual)
        return solution


SOLVERS: Registry[KKTSolver] = Registry("solver")
"""KKT backends. A factory is ``factory(model, corrector_gains, options) -> KKTSolver`` with the
:class:`~pinstab.model.ConstrainedModel` and the stabilizer's Baumgarte gains (None when its term is
not of Baumgarte form); an entry's capabilities are the row kinds its solver takes."""


def solvers_with(kinds: frozenset[RowKind]) -> list[str]:
    """The registered solvers whose row kinds cover ``kinds``."""
    return [entry.name for entry in SOLVERS.entries() if kinds <= entry.capabilities]


def check_row_kinds(solver: type[KKTSolver], model: ConstrainedModel) -> None:
    """Refuse a model whose rows the solver does not take, naming the rows and the solvers that do.

    Raises:
        SolverError: some row kind of the model is not in ``solver.row_kinds``.
    """
    needed = model.constraints.layout.kinds
    missing = needed - solver.row_kinds
    if not missing:
        return
    blocks = [c.name for c in model.constraints.constraints if c.row_kind in missing]
    kinds = ", ".join(sorted(kind.value for kind in missing))
    raise SolverError(
        f"solver {solver.name!r} does not take {kinds} rows (constraints {', '.join(blocks)}); "
        f"solvers that do: {choices(solvers_with(needed))}"
    )
