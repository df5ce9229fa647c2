"""``pinocchio``: Pinocchio's own ``constraintDynamics`` (sparse constrained Cholesky + proximal loop).

It fits scenes whose constraints are frame closures: ``point`` maps to ``CONTACT_3D`` and ``weld`` to
``CONTACT_6D`` (both in LOCAL_WORLD_ALIGNED); ``planar-point`` maps to ``CONTACT_3D`` when the
out-of-plane row is identically redundant (a planar mechanism), which is checked. Its stabilization
term can only be Pinocchio's Baumgarte corrector (scalar Kp, Kd); ``desired_contact_acceleration``
is not used by Pinocchio 4.1's algorithm, so no other term can be injected.

Pinocchio's proximal solve can lose the constraints near singular configurations, so every solve is
checked: when ``|G a - rhs|`` exceeds :data:`~pinstab.solvers.base.ACCEPTED_RESIDUAL` (relative to
the size of the terms) the same problem is solved again by ProxQP and the fallback is counted.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ..constraints import Constraint, FrameClosure, RowKind
from ..errors import SolverError
from .base import ACCEPTED_RESIDUAL, SOLVERS, KKTProblem, KKTSolution, KKTSolver, check_row_kinds, primal_residual
from .proxsuite_ import ProxsuiteSolver

if TYPE_CHECKING:
    from ..model import ConstrainedModel

CONTACT_TYPES = {
    "point": pin.ContactType.CONTACT_3D,
    "planar-point": pin.ContactType.CONTACT_3D,
    "weld": pin.ContactType.CONTACT_6D,
}


class PinocchioSolver(KKTSolver):
    """Pinocchio ``constraintDynamics`` as a KKT backend.

    Args:
        model: the scene model.
        constraints: the scene's constraint blocks (frame closures only).
        kp: Baumgarte proportional gain [1/s^2] (Pinocchio's Kp = beta^2).
        kd: Baumgarte derivative gain [1/s] (Pinocchio's Kd = 2 alpha).
        mu: proximal regularization of Pinocchio's solve.
    """

    name = "pinocchio"

    def __init__(
        self, model: pin.Model, constraints: list[Constraint], kp: float = 0.0, kd: float = 0.0, mu: float = 1e-12
    ) -> None:
        super().__init__()
        self.model = model
        self.data = model.createData()
        self.models = pin.StdVec_RigidConstraintModel()
        self.datas = pin.StdVec_RigidConstraintData()
        self.closures: list[FrameClosure] = []
        for constraint in constraints:
            if not isinstance(constraint, FrameClosure) or constraint.row_kind != RowKind.EQUALITY:
                raise SolverError(
                    f"solver pinocchio: constraint {constraint.name!r} is not a frame closure; Pinocchio's "
                    "constraintDynamics only takes point/weld closures. Use solver 'proxsuite' or 'dense'."
                )
            self.closures.append(constraint)
            self.models.append(self._rigid_model(constraint, kp, kd))
        for rcm in self.models:
            self.datas.append(rcm.createData())
        pin.initConstraintDynamics(model, self.data, self.models, self.datas)
        self.settings = pin.ProximalSettings(1e-14, 1e-12, mu, 50)
        self._checked_planar = False
        self._fallback = ProxsuiteSolver()
        self.kp, self.kd = float(kp), float(kd)
        # direct mode (see direct()): point-like closures only, each a 3-D contact in world axes
        self.direct_capable = all(c.kind in ("point", "planar-point") for c in self.closures)
        if self.direct_capable and self.closures:
            self._rows = np.zeros((sum(c.rows for c in self.closures), 3 * len(self.closures)))
            start = 0
            for index, closure in enumerate(self.closures):
                self._rows[start : start + closure.rows, 3 * index : 3 * index + 3] = closure.selection
                start += closure.rows
            self._target = np.zeros(3 * len(self.closures))
            self._data_list = list(self.datas)

    def _rigid_model(self, closure: FrameClosure, kp: float, kd: float) -> pin.RigidConstraintModel:
        frame_a = self.model.frames[closure.frame_a]
        if closure.frame_b is None:
            joint_b, placement_b = 0, closure.world_placement_b
        else:
            frame_b = self.model.frames[closure.frame_b]
            joint_b, placement_b = frame_b.parentJoint, frame_b.placement
        rcm = pin.RigidConstraintModel(
            CONTACT_TYPES[closure.kind],
            self.model,
            frame_a.parentJoint,
            frame_a.placement,
            joint_b,
            placement_b,
            pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
        )
        rcm.name = closure.name
        rcm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(float(kp), float(kd)))
        return rcm

    @property
    def corrector_gains(self) -> tuple[float, float]:
        """(Kp, Kd) of the corrector Pinocchio applies [1/s^2, 1/s]."""
        return (self.kp, self.kd)

    def _check_planar(self, q: np.ndarray) -> None:
        """planar-point rows stand in for 3-D contacts only if the third row is identically zero."""
        data = self.model.createData()
        pin.computeJointJacobians(self.model, data, q)
        pin.updateFramePlacements(self.model, data)
        for closure in self.closures:
            if closure.kind != "planar-point":
                continue
            jac = pin.getFrameJacobian(self.model, data, closure.frame_a, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
            if closure.frame_b is not None:
                jac = (
                    jac
                    - pin.getFrameJacobian(self.model, data, closure.frame_b, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[
                        :3
                    ]
                )
            normal = np.cross(closure.selection[0], closure.selection[1])
            if np.abs(normal @ jac).max() > 1e-12:
                raise SolverError(
                    f"solver pinocchio: planar-point closure {closure.name!r} is not on a planar mechanism "
                    "(its out-of-plane motion is not blocked by the joints), so it has no Pinocchio equivalent. "
                    "Use solver 'proxsuite' or 'dense'."
                )
        self._checked_planar = True

    def solve(self, problem: KKTProblem) -> KKTSolution:
        if not self._checked_planar:
            self._check_planar(problem.q)
        acceleration = pin.constraintDynamics(
            self.model, self.data, problem.q, problem.v, problem.tau, self.models, self.datas, self.settings
        )
        acceleration = np.array(acceleration)
        residual_force = problem.mass_matrix @ acceleration - problem.free_force
        multipliers = np.linalg.lstsq(problem.jacobian.T, residual_force, rcond=1e-12)[0]
        primal = primal_residual(problem, acceleration)
        if np.all(np.isfinite(acceleration)) and not primal <= ACCEPTED_RESIDUAL:
            return self._fall_back(problem)
        # the multipliers are the least-squares ones of M a - f = G^T lambda: not measured again
        iterations = int(self.settings.iter)
        return self.record(KKTSolution(acceleration, multipliers, "solved", iterations, primal, math.nan))

    def _fall_back(self, problem: KKTProblem) -> KKTSolution:
        """Solve with ProxQP (counted as a fallback; its statistics join this backend's)."""
        self.statistics.fallbacks += 1
        solution = self._fallback.solve(problem)
        return self.record(dataclasses.replace(solution, status=f"fallback {solution.status}"))

    def direct(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> KKTSolution | None:
        """Pinocchio's constraint dynamics with its own Baumgarte corrector, checked from Pinocchio's own
        data (no pinstab kinematics pass): the constraint Jacobian, the contact points and their drift
        accelerations give ``G a + gamma0 = -Kp phi - Kd G v``, which must hold to ACCEPTED_RESIDUAL (relative).

        Returns None when the check fails (the caller solves the problem the general way). Only for
        point and planar-point closures (``direct_capable``).
        """
        if not self._checked_planar:
            self._check_planar(q)
        model, data, datas = self.model, self.data, self.datas
        acceleration = pin.constraintDynamics(model, data, q, v, tau, self.models, datas, self.settings)
        if not self.closures:
            return self.record(KKTSolution(acceleration, np.zeros(0)))
        jac = pin.getConstraintsJacobian(model, data, self.models, datas)
        target = self._target  # -gamma0 - Kp phi, contact by contact, in world axes
        for index, contact in enumerate(self._data_list):
            rows = slice(3 * index, 3 * index + 3)
            target[rows] = contact.contact2_acceleration_drift.linear - contact.contact1_acceleration_drift.linear
            target[rows] -= self.kp * (contact.oMc1.translation - contact.oMc2.translation)
        rhs = self._rows @ (target - self.kd * (jac @ v))
        residual = self._rows @ (jac @ acceleration) - rhs
        # the residual against the size of its terms, in the Euclidean norm (dot products are the
        # cheapest reductions): |G a - rhs| <= tol (|rhs| + |G|_F |a|), squared
        flat = jac.ravel()
        scale = rhs @ rhs + (flat @ flat) * (acceleration @ acceleration)
        if not residual @ residual <= ACCEPTED_RESIDUAL**2 * scale:
            self.statistics.fallbacks += 1
            return None
        primal = math.sqrt(residual @ residual / scale) if scale > 0 else 0.0
        return self.record(
            KKTSolution(acceleration, self._rows @ data.lambda_c, "solved", int(self.settings.iter), primal, math.nan)
        )


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
    return PinocchioSolver(model.model, model.constraints.constraints, *corrector_gains, mu=options.mu)
