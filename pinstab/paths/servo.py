"""The servo path: prescribed joint relations realized by controls, evaluated compiled.

A scene whose constraints are all prescribed ``joint-relation`` rows ``S q = c(t)`` (``[[servos]]``; S constant)
with a Baumgarte term needs per evaluation only M, h and a few small solves (docs/mathematics.md section 5, with no real
constraint rows):

    a0 = M^-1 (tau - h),    D = S M^-1 B,    D u = c'' - Kd (S v - c') - Kp (S q - c) - S a0,    a = a0 + M^-1 B u,

u the least-norm solution. The general path forms the same through pinstab's kinematics
(:class:`~pinstab.servo.ServoSolver`, which calls the same compiled solve up to the controls,
:func:`pinstab.kernels.servo_parts`), several times the cost of the dynamics on a small mechanism; the compiled
kernel (``cpp/servo_kernel.cpp``: Pinocchio's ``crba`` and ``nonLinearEffects``, a Cholesky factorization of M,
the targets' compiled forms of :meth:`~pinstab.constraints.targets.TargetTrajectory.compiled`) evaluates it in
microseconds, and the compiled step loop takes its steps. Where D loses rank (or its determinant changes sign)
or a control leaves its bounds, an evaluation is not used: the general solve takes it and raises
:class:`~pinstab.errors.ServoInfeasibleError` or solves the bounded problem.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..actuation import Actuation
from ..constraints import Constraint
from ..constraints.joint_relation import JointRelation
from ..kernels import ServoKernel
from ..model import ConstrainedModel


def servo_obstacle(constraints: list[Constraint], actuation: Actuation | None) -> str | None:
    """Why the servo path cannot evaluate these constraints (naming the first that it cannot), or None."""
    if actuation is None or not constraints:
        return "no prescribed constraints with an [actuation]"
    for constraint in constraints:
        if not constraint.prescribed:
            return f"constraint {constraint.name!r} is a real constraint beside the servos (the general path's solve)"
        if not isinstance(constraint, JointRelation):
            return (
                f"servo {constraint.name!r} is a {type(constraint).__name__}, not a joint-relation (rows linear in q)"
            )
        if constraint.trajectory.compiled(0) is None:
            return f"servo {constraint.name!r}'s target has no compiled form"
    return None


class ServoDynamics:
    """The compiled servo solve of a scene's prescribed joint relations (see :func:`servo_obstacle`).

    Args:
        model: the Pinocchio model. relations: the prescribed joint relations, one row each.
        actuation: B, the controls' names and bounds. kp: corrector stiffness [1/s^2]. kd: corrector damping [1/s].
        rank_tolerance: :data:`pinstab.servo.RANK_TOLERANCE`, for the rank of D free of the units of each row and
            control (:func:`pinstab.kernels.servo_realizability`, the general solve's rule).

    Attributes:
        kernel: the compiled evaluation (``cpp/servo_kernel.cpp``).
        unusable: the last :meth:`acceleration` is not to be used (rank lost, a sign change, a bound, non-finite).
        status: the solver status its solves count under.
        worst_residual: not measured (0): the controls are the least-norm solution of the rows, which are checked for
            rank before it is used.
    """

    status = "servo"
    worst_residual = 0.0

    def __init__(
        self,
        model: pin.Model,
        relations: list[JointRelation],
        actuation: Actuation,
        kp: float,
        kd: float,
        rank_tolerance: float,
    ) -> None:
        rows = np.zeros((len(relations), model.nv))
        position_rows = np.zeros((len(relations), model.nq))
        for index, relation in enumerate(relations):
            rows[index, relation.v_indices] = relation.row
            position_rows[index, relation.q_indices] = relation.row
        self.kernel = ServoKernel(
            model,
            rows,
            position_rows,
            actuation.matrix,
            actuation.lower,
            actuation.upper,
            [relation.trajectory.compiled(0) for relation in relations],
            float(kp),
            float(kd),
            rank_tolerance,
        )
        self.unusable = False

    def force(self, model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The applied forces the kernel takes [N, N m]: every force element's (in Python)."""
        return model.applied_force_at(q, v, t)

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        """Joint accelerations [m/s^2, rad/s^2] at (t, q, v) under the applied forces ``tau`` [N, N m], at that
        ``stage`` of a step; check :attr:`unusable` before using them."""
        acceleration, usable = self.kernel.acceleration(q, v, tau, t, stage)
        self.unusable = not usable
        return acceleration

    @property
    def last_sign(self) -> tuple[float, float] | None:
        """(time [s], sign of det D) of the kernel's last evaluation whose square D was usable
        (:func:`pinstab.kernels.servo_realizability`), or None."""
        return self.kernel.last_sign
