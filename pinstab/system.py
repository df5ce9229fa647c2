"""The stepping system: a :class:`~pinstab.model.ConstrainedModel` with a stabilizer and a KKT backend,
``(q, v, t) -> (a, lambda)`` (MATH.md eq. 3)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .constraints import ConstraintValues
from .errors import DivergenceError, PinstabError
from .model import ConstrainedModel
from .scene import Scene
from .solvers import SOLVERS, KKTProblem, KKTSolver
from .stabilizers import STABILIZERS, Stabilizer

DEFAULT_SOLVER = "proxsuite"


@dataclass
class Evaluation:
    """Dynamics at one state: accelerations [m/s^2, rad/s^2], multipliers, constraint values (None on
    the direct Pinocchio path, which does not form them)."""

    acceleration: np.ndarray
    multipliers: np.ndarray
    values: ConstraintValues | None


class ConstrainedSystem:
    """MATH.md eq. (3): ``M a + h = tau + G^T lambda``, ``G a = -gamma0 + gamma_stab``.

    Args:
        model: the constrained model.
        stabilizer: provides gamma_stab and post-step corrections.
        solver: the KKT backend.

    Attributes:
        direct: the whole evaluation runs on the solver's own path (Pinocchio computing its own
            kinematics and applying the stabilizer's Baumgarte term in its corrector), checked there
            and done the general way when the check fails.
    """

    def __init__(self, model: ConstrainedModel, stabilizer: Stabilizer, solver: KKTSolver) -> None:
        self.model = model
        self.stabilizer = stabilizer
        self.solver = solver
        self.direct = (
            solver.direct_capable
            and solver.corrector_gains is not None
            and stabilizer.baumgarte_gains() == solver.corrector_gains
            and not model.forces_need_kinematics
        )

    def dynamics(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> Evaluation:
        """Accelerations and multipliers at (q, v, t); ``stage`` is the integrator's stage index.

        Raises:
            DivergenceError: the state (or an integrator stage) is not finite.
        """
        if not (np.isfinite(q).all() and np.isfinite(v).all()):
            raise DivergenceError(f"non-finite state reached at t = {t:.6g} s", t, q, v)
        model = self.model
        if self.direct:
            solution = self.solver.direct(q, v, model.applied_force(v, t))
            if solution is not None:
                if not np.isfinite(solution.acceleration).all():
                    raise DivergenceError(f"non-finite acceleration from Pinocchio at t = {t:.6g} s", t, q, v)
                return Evaluation(solution.acceleration, solution.multipliers, None)
        terms = model.dynamics_terms(q, v, t)
        values = terms.values
        rhs = -values.drift
        gamma = self.stabilizer.stabilization_term(model, q, v, t, values, stage)
        if gamma is not None:
            rhs = rhs + gamma
        problem = KKTProblem(
            q,
            v,
            t,
            terms.tau,
            terms.mass_matrix,
            terms.tau - terms.bias,
            values.jacobian,
            rhs,
            model.constraints.layout,
        )
        solution = self.solver.solve(problem)
        if not np.isfinite(solution.acceleration).all():
            raise DivergenceError(f"non-finite acceleration from solver {self.solver.name} at t = {t:.6g} s", t, q, v)
        return Evaluation(solution.acceleration, solution.multipliers, values)


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
        solver: a registered KKT backend; None: the method's own, else ``proxsuite``.
        solver_options: the backend's options.
        method_options: the method's options (e.g. ``kp``, ``kd``).

    Methods with step-dependent gains (``mukharlyamov``) need ``system.stabilizer.bind(...)`` before
    ``system.dynamics``; :func:`~pinstab.simulate.simulate` does it.
    """
    model = scene if isinstance(scene, ConstrainedModel) else ConstrainedModel(scene)
    stabilizer = STABILIZERS.build(method, options=method_options)
    name = solver or stabilizer.required_solver or DEFAULT_SOLVER
    if stabilizer.required_solver is not None and name != stabilizer.required_solver:
        raise PinstabError(f"method {method!r} runs on solver {stabilizer.required_solver!r}, not {name!r}")
    backend = SOLVERS.build(name, model, stabilizer.baumgarte_gains(), options=solver_options)
    return ConstrainedSystem(model, stabilizer, backend)
