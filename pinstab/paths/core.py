"""The core path: any stack of the standard rows with joint springs and dampers, evaluated compiled.

A scene whose constraints all have compiled rows (:meth:`~pinstab.constraints.base.Constraint.compiled_rows`: point,
planar-point, weld, revolute and prismatic closures, joint relations), all equalities and none prescribed, whose force
elements all have the compiled form ``joint-spring`` (:meth:`~pinstab.forces.base.ForceElement.compiled_form`) and
whose stabilization term is Baumgarte's, needs per evaluation one kinematics pass, the rows, and one KKT solve: the
core kernel (``cpp/core_kernel.cpp``) makes them in one call, on any joint types (free flyers, balls). Its KKT solve
factors M and the Delassus matrix G M^-1 G^T by Cholesky where the rows are independent by a margin (the general
path's direct-solve test, :data:`~pinstab.solvers.proxsuite_.DIRECT_PIVOT`), and otherwise (redundant loops, as the
full Cassie's, or a near-singular configuration) runs proximal iterations from zero multipliers: the least-norm
multipliers and, where the rows are inconsistent, the least-squares accelerations. An evaluation whose solve does not
reach :data:`~pinstab.solvers.base.ACCEPTED_RESIDUAL` is not used: the general path solves it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ..constraints import Constraint, RowKind
from ..forces.base import ForceElement
from ..kernels import CoreKernel
from ..model import ConstrainedModel

CORE_FORCE_KINDS = ("joint-spring",)
"""Compiled force forms the core kernel takes."""
# the pseudo-inverse's cutoff on the Delassus matrix's eigenvalues, relative to its largest: rows independent by less
# (a singular value of M^-1/2 G^T under 1e-6 of the largest) would need forces 1e12 times the others' for what is the
# rounding or drift of redundant rows (the full Cassie: 10 redundant rows at 1e-16 .. 1e-14, its near-singular
# shin-spring triangles at 1.4e-14, its least genuine eigenvalue at 1.8e-8)
CUTOFF = 1e-12


def core_obstacle(constraints: list[Constraint], forces: list[ForceElement], rows: dict[str, slice]) -> str | None:
    """Why the core kernel cannot evaluate these constraints and forces (naming the first it cannot), or None."""
    for constraint in constraints:
        if constraint.compiled_rows() is None:
            return f"constraint {constraint.name!r} ({type(constraint).__name__}) has no compiled rows"
        if constraint.prescribed:
            return f"constraint {constraint.name!r} is prescribed (a servo: the controls realize it)"
        if constraint.row_kind != RowKind.EQUALITY:
            return f"constraint {constraint.name!r} has {constraint.row_kind.value} rows (the core takes equalities)"
    for element in forces:
        form = element.compiled_form(rows)
        if form is None or form["kind"] not in CORE_FORCE_KINDS:
            return f"force {element.name!r} ({type(element).__name__}) has no compiled form the core takes"
    return None


class CoreDynamics:
    """The compiled core evaluation (see :func:`core_obstacle`).

    Args:
        model: the Pinocchio model. constraints: the scene's constraints. forces: its force elements.
        rows: each constraint's rows in the stack by name. kp: corrector stiffness [1/s^2]. kd: corrector damping
            [1/s]. direct_pivot: the Delassus matrix's smallest Cholesky pivot (squared) over its largest diagonal
            entry below which the rows count as dependent. accepted: the relative primal residual an evaluation must
            reach to be used.

    Attributes:
        kernel: the compiled evaluation (``cpp/core_kernel.cpp``).
        unusable: the last :meth:`acceleration` is not to be used (the general path solves it).
        status: the solver status its solves count under.
    """

    status = "core"

    def __init__(
        self,
        model: pin.Model,
        constraints: list[Constraint],
        forces: list[ForceElement],
        rows: dict[str, slice],
        kp: float,
        kd: float,
        direct_pivot: float,
        accepted: float,
    ) -> None:
        settings: dict[str, Any] = {
            "direct_pivot": direct_pivot,
            "cutoff": CUTOFF,
            "accepted": accepted,
        }
        springs = [element.compiled_form(rows) for element in forces]
        blocks = [constraint.compiled_rows() for constraint in constraints]
        self.kernel = CoreKernel(model, blocks, springs, float(kp), float(kd), settings)
        self._zero = np.zeros(model.nv)
        self._zero.flags.writeable = False
        self.unusable = False

    def force(self, model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The applied forces the kernel takes besides its own [N, N m]: none (every element is compiled)."""
        return self._zero

    def status_counts(self) -> dict[str, int]:
        """The kernel's evaluations by how they were solved (``core cholesky``, ``core pseudo-inverse``, ``core
        pseudo-inverse, not accepted``: solved by the general path instead)."""
        return {f"{self.status} {status}": count for status, count in self.kernel.status_counts.items()}

    @property
    def worst_residual(self) -> float:
        """The largest relative ``|G a - rhs|`` of the evaluations used [-] (the general path's measure)."""
        return self.kernel.worst_residual

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, t: float) -> np.ndarray:
        """Joint accelerations [m/s^2, rad/s^2] at (t, q, v) under the applied forces ``tau`` [N, N m] besides the
        compiled elements'; check :attr:`unusable` before using them."""
        acceleration, usable = self.kernel.acceleration(q, v, tau, t)
        self.unusable = not usable
        return acceleration
