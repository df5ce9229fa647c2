"""The core path: any stack of the standard rows with the force elements that have a compiled form, evaluated compiled.

A scene whose constraints all have compiled rows (:meth:`~pinstab.constraints.base.Constraint.compiled_rows`: point,
planar-point, weld, revolute and prismatic closures, joint relations, fingertip contacts of every contact model), all
equalities and none prescribed, and whose stabilization term is Baumgarte's, needs per evaluation one kinematics pass,
the rows, the forces and one KKT solve. Force elements with a compiled form the core takes (``joint-spring``, ``hold``,
``wrench``: :meth:`~pinstab.forces.base.ForceElement.compiled_form`) are computed in the kernel; the others (an
object-level grasp controller, a user's element) in Python at each evaluation, after a kinematics pass of pinstab's
where they read it, and passed in (the path's reason names them). The core kernel (``cpp/core_kernel.cpp``) makes the
rest in one call, on any joint types (free flyers, balls), under gravity that tilts in time where the scene has a
``[tilt]``. Its KKT solve factors M and the Delassus matrix G M^-1 G^T by Cholesky where the rows are independent by a
margin (the general path's direct-solve test, :data:`~pinstab.solvers.proxsuite_.DIRECT_PIVOT`), and otherwise
(redundant loops, as the full Cassie's, or a near-singular configuration) takes its pseudo-inverse (:data:`CUTOFF`): the
least-norm multipliers and, where the rows are inconsistent, the least-squares accelerations. An evaluation is not used,
and the general path solves it (or names what fails), where the solve misses
:data:`~pinstab.solvers.base.ACCEPTED_RESIDUAL`, a fingertip contact's force leaves its limits, or a hold's
least-squares forces leave a cone or the cap (its QP takes them).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ..constraints import Constraint, RowKind
from ..contact.models import MARGIN_SLACK
from ..forces.base import ForceElement
from ..kernels import CoreKernel
from ..model import ConstrainedModel
from ..scene import GravityTilt

CORE_FORCE_KINDS = ("joint-spring", "hold", "wrench")
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
    return None


def _compiled(element: ForceElement, rows: dict[str, slice]) -> dict[str, Any] | None:
    """The element's compiled form when the core takes it, else None."""
    form = element.compiled_form(rows)
    return form if form is not None and form["kind"] in CORE_FORCE_KINDS else None


class CoreDynamics:
    """The compiled core evaluation (see :func:`core_obstacle`).

    Args:
        model: the Pinocchio model. constraints: the scene's constraints. forces: its force elements (those without
            a compiled form the core takes are evaluated in Python: :meth:`force`). tilt: the scene's gravity tilt, or
            None.
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
        tilt: GravityTilt | None = None,
    ) -> None:
        settings: dict[str, Any] = {
            "direct_pivot": direct_pivot,
            "cutoff": CUTOFF,
            "accepted": accepted,
            "margin_slack": MARGIN_SLACK,
        }
        forms = [_compiled(element, rows) for element in forces]
        blocks = [constraint.compiled_rows() for constraint in constraints]
        turning = None if tilt is None else tilt.compiled_form()
        compiled = [form for form in forms if form is not None]
        self.kernel = CoreKernel(model, blocks, compiled, float(kp), float(kd), settings, turning)
        self._python = [element for element, form in zip(forces, forms, strict=True) if form is None]
        self._reads_kinematics = any(element.needs_kinematics for element in self._python)
        self._zero = np.zeros(model.nv)
        self._zero.flags.writeable = False
        self.unusable = False

    @property
    def python_forces(self) -> list[str]:
        """The force elements evaluated in Python (no compiled form the core takes), by name."""
        return [element.name for element in self._python]

    def force(self, model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The applied forces the kernel takes besides its own [N, N m]: those of the elements without a compiled form
        the core takes, evaluated in Python (after a kinematics pass of pinstab's where one reads it)."""
        if not self._python:
            return self._zero
        if self._reads_kinematics:
            return model.forces_at(q, v, t, self._python)
        return sum((element.generalized_force(model.kin, v, t) for element in self._python), np.zeros(len(v)))

    @property
    def takes_every_force(self) -> bool:
        """Whether the kernel computes every force element itself (the compiled loop passes no forces)."""
        return not self._python

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
