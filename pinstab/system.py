"""A scene's equations of motion with a stabilizer and a KKT backend: (q, v, t) -> (a, lambda)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .constraints import ConstraintValues
from .errors import DivergenceError
from .forces import JointTorque
from .kinematics import Kinematics, symmetric_mass_matrix
from .scene import Scene
from .solvers import KKTProblem, KKTSolver, PinocchioSolver
from .stabilizers import BaumgarteStabilizer, NoStabilizer, PostStabilizer, ProjectionStabilizer
from .stabilizers.base import Stabilizer


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
        scene: the scene (model, constraints, force elements).
        stabilizer: provides gamma_stab and post-step corrections.
        solver: the KKT backend.
    """

    def __init__(self, scene: Scene, stabilizer: Stabilizer, solver: KKTSolver) -> None:
        self.scene = scene
        self.model = scene.model
        self.kin = Kinematics(scene.model)
        self.constraints = scene.constraint_set
        self.forces = scene.forces
        self.stabilizer = stabilizer
        self.solver = solver
        self._energy_data = scene.model.createData()
        # Pinocchio can do the whole evaluation itself when its corrector is the method's term and no
        # force element needs pinstab's kinematics: the direct path (checked inside, general path if not)
        self.direct = (
            isinstance(solver, PinocchioSolver)
            and solver.direct_capable
            and stabilizer.baumgarte_gains() == (solver.kp, solver.kd)
            and isinstance(stabilizer, (BaumgarteStabilizer, NoStabilizer, ProjectionStabilizer, PostStabilizer))
            and all(isinstance(element, JointTorque) for element in scene.forces)
            and len(self.constraints.constraints) == len(solver.closures)
        )

    @property
    def nv(self) -> int:
        return self.model.nv

    def applied_force(self, v: np.ndarray, t: float) -> np.ndarray:
        """Sum of force elements [N, N m]; kinematics must be current."""
        tau = np.zeros(self.model.nv)
        for element in self.forces:
            tau += element.generalized_force(self.kin, v, t)
        return tau

    def dynamics(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> Evaluation:
        """Accelerations and multipliers at (q, v, t); ``stage`` is the integrator's stage index.

        Raises:
            DivergenceError: the state (or an integrator stage) is not finite.
        """
        if not (np.isfinite(q).all() and np.isfinite(v).all()):
            raise DivergenceError(f"non-finite state reached at t = {t:.6g} s", t, q, v)
        if self.direct:
            solution = self.solver.direct(q, v, self.applied_force(v, t))
            if solution is not None:
                if not np.isfinite(solution.acceleration).all():
                    raise DivergenceError(f"non-finite acceleration from Pinocchio at t = {t:.6g} s", t, q, v)
                return Evaluation(solution.acceleration, solution.multipliers, None)
        self.kin.update(q, v)
        tau = self.applied_force(v, t)
        values = self.constraints.values(self.kin, q, v, t, with_drift=True)
        rhs = -values.drift
        gamma = self.stabilizer.stabilization_term(self, q, v, t, values, stage)
        if gamma is not None:
            rhs = rhs + gamma
        problem = KKTProblem(q, v, tau, self.kin.mass_matrix, tau - self.kin.bias, values.jacobian, rhs)
        solution = self.solver.solve(problem)
        if not np.isfinite(solution.acceleration).all():
            raise DivergenceError(f"non-finite acceleration from solver {self.solver.name} at t = {t:.6g} s", t, q, v)
        return Evaluation(solution.acceleration, solution.multipliers, values)

    def constraint_values(self, q: np.ndarray, v: np.ndarray, t: float) -> ConstraintValues:
        """phi, G, g at (q, v, t) without drift terms (one Jacobian pass)."""
        self.kin.update_jacobians(q)
        return self.constraints.values(self.kin, q, v, t, with_drift=False)

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Joint-space inertia M(q), symmetric [kg, kg m^2]."""
        nv = self.model.nv
        return symmetric_mass_matrix(self.model, self._energy_data, q, np.empty((nv, nv)), self.kin.lower)

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Kinetic + gravity + spring energy [J]; placements at q must be current in ``kin``."""
        data = self._energy_data
        kinetic = pin.computeKineticEnergy(self.model, data, q, v)
        potential = pin.computePotentialEnergy(self.model, data, q)
        springs = sum(element.potential_energy(self.kin) for element in self.forces)
        return float(kinetic + potential + springs)

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """q (+) dq on the configuration group."""
        return pin.integrate(self.model, q, dq)
