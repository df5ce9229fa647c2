"""The core path: any stack of the standard rows with the force elements that have a compiled form, evaluated compiled.

A scene whose constraints all have compiled rows (:meth:`~pinstab.constraints.base.Constraint.compiled_rows`: point,
planar-point, weld, revolute and prismatic closures, joint relations, fingertip contacts of every contact model), all
equalities and none prescribed, and whose stabilization term is Baumgarte's, needs per evaluation one kinematics pass,
the rows, the forces and one KKT solve. Force elements with a compiled form the core takes (``joint-spring``, ``hold``,
``wrench``, ``spring-damper``, ``joint-torque``: :meth:`~pinstab.forces.base.ForceElement.compiled_form`) are computed
in the kernel; the others (an object-level grasp controller, a user's element) in Python at each evaluation, after a
kinematics pass of pinstab's where they read it, and passed in (the path's reason names them). The core kernel
(``cpp/core_kernel.cpp``) makes the rest in one call, on any joint types (free flyers, balls), under gravity that tilts
in time where the scene has a ``[tilt]``. Its KKT solve factors M and the Delassus matrix G M^-1 G^T by Cholesky where
the rows are independent by a margin (the general path's direct-solve test,
:data:`~pinstab.solvers.proxsuite_.DIRECT_PIVOT`), and otherwise (redundant loops, as the full Cassie's, or a
near-singular configuration) takes its pseudo-inverse (:data:`CUTOFF`): the least-norm multipliers and, where the rows
are inconsistent, the least-squares accelerations. An evaluation is not used, and the general path solves it (or names
what fails), where the solve misses :data:`~pinstab.solvers.base.ACCEPTED_RESIDUAL`, a fingertip contact's force leaves
its limits, or a hold's least-squares forces leave a cone or the cap (its QP takes them).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..constraints import Constraint, ConstraintSet, RowKind
from ..contact.models import MARGIN_SLACK
from ..errors import GraspLostError
from ..forces.base import ForceElement, batched
from ..kernels import CoreKernel, CoreProjection, RowBlock
from ..model import ConstrainedModel
from ..projection import CUTOFF as PROJECTION_CUTOFF
from ..projection import not_finite

CORE_FORCE_KINDS = ("joint-spring", "hold", "wrench", "spring-damper", "joint-torque")
"""Compiled force forms the core kernel takes."""
# the pseudo-inverse's cutoff on the Delassus matrix's eigenvalues, relative to its largest: rows independent by less
# (a singular value of M^-1/2 G^T under 1e-6 of the largest) would need forces 1e12 times the others' for what is the
# rounding or drift of redundant rows (the full Cassie: 10 redundant rows at 1e-16 .. 1e-14, its near-singular
# shin-spring triangles at 1.4e-14, its least genuine eigenvalue at 1.8e-8)
CUTOFF = 1e-12


class CoreTerm(NamedTuple):
    """The stabilization term in the core kernel's form ``gamma_stab = -K (G v + g_t) - S phi``
    (``cpp/core_kernel.hpp`` CoreTerm; a stabilizer gives it:
    :meth:`~pinstab.stabilizers.base.Stabilizer.core_term`).

    Attributes:
        stiffness: S [1/s^2]. velocity_gains: K per row (s,) [1/s].
        held: computed at a step's first stage and held over its other stages.
        inertial: Mukharlyamov's inertial variant instead of S and K (``cpp/inertial_term.hpp``: a dict of H and B,
            s x s, the difference step [s] of dD/dt and the cutoff of D^+), or None.
    """

    stiffness: float
    velocity_gains: np.ndarray
    held: bool
    inertial: dict | None = None


def core_obstacle(constraints: list[Constraint]) -> str | None:
    """Why the core kernel cannot evaluate these constraints (naming the first it cannot), or None: a prescribed block
    (a servo) or one whose rows are not equalities (a unilateral contact, a cone)."""
    for constraint in constraints:
        if constraint.prescribed:
            return f"constraint {constraint.name!r} is prescribed (a servo: the controls realize it)"
        if constraint.row_kind != RowKind.EQUALITY:
            return f"constraint {constraint.name!r} has {constraint.row_kind.value} rows (the core takes equalities)"
    return None


def _compiled(element: ForceElement, rows: dict[str, slice]) -> dict[str, Any] | None:
    """The element's compiled form when the core takes it, else None."""
    form = element.compiled_form(rows)
    return form if form is not None and form["kind"] in CORE_FORCE_KINDS else None


def _python_rows(constraint: Constraint) -> RowBlock:
    """The placeholder of a block whose rows Python gives at each evaluation (kind 6)."""
    block = RowBlock(6, -1, -1, np.eye(4), np.zeros((0, 3)))
    block.python_rows, block.holonomic = constraint.rows, constraint.holonomic
    return block


class PythonPart:
    """What Python computes at each evaluation of the core: the rows of the blocks without compiled rows and the forces
    of the elements without a compiled form the core takes, after one kinematics pass of pinstab's at the state (under
    the scene's gravity at t), and the force limits of those blocks (the kernel calls :meth:`evaluate` and
    :meth:`holds`, ``cpp/core_kernel.hpp`` PythonPart).

    Args:
        model: the constrained model. blocks: the constraints evaluated here. elements: the force elements.
    """

    def __init__(self, model: ConstrainedModel, blocks: list[Constraint], elements: list[ForceElement]) -> None:
        self.model, self.blocks, self.elements = model, blocks, elements
        self._evaluated = batched(elements)  # what an evaluation calls: those of a class batched
        self._stack = ConstraintSet(blocks, model.nv)
        self._reads_kinematics = bool(blocks) or any(element.needs_kinematics for element in elements)
        self._limited = any(block.limits_force for block in blocks)

    def evaluate(
        self, t: float, q: np.ndarray, v: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(G, phi, g_t, gamma0) of the blocks, stacked (phi zero on nonholonomic rows) [m or rad ...], and the
        elements' forces [N, N m] at (t [s], q, v)."""
        model, elements = self.model, self._evaluated
        force = model.forces_at(q, v, t, elements) if self._reads_kinematics else model.applied_force(v, t, elements)
        values = self._stack.values(model.kin, q, v, t, with_drift=True)  # no blocks: empty, nothing read
        return values.jacobian, values.phi, values.time_term, values.drift, force

    def holds(self, t: float, multipliers: np.ndarray) -> bool:
        """Whether the multipliers (every row) keep the blocks' force limits at t [s] (what
        :meth:`~pinstab.constraints.stack.ConstraintSet.check_forces` would not refuse)."""
        if not self._limited:
            return True
        try:
            self.model.constraints.check_forces(multipliers, t)
        except GraspLostError:
            return False
        return True


class CoreDynamics:
    """The compiled core evaluation (see :func:`core_obstacle`).

    Args:
        model: the constrained model. term: the stabilization term in the core's form (S, K per row, held over a
            step's stages or not, or Mukharlyamov's inertial one: :class:`CoreTerm`). direct_pivot: the Delassus
            matrix's smallest Cholesky pivot (squared) over its largest diagonal entry below which the rows count as
            dependent. accepted: the relative primal residual an evaluation must reach to be used.

    Attributes:
        kernel: the compiled evaluation (``cpp/core_kernel.cpp``).
        python: the blocks and force elements evaluated in Python (:class:`PythonPart`), or None.
        held: the term is held over a step's stages (:meth:`held_term`).
        unusable: the last :meth:`acceleration` is not to be used (the general path solves it).
        status: the solver status its solves count under.
    """

    status = "core"

    def __init__(self, model: ConstrainedModel, term: CoreTerm, direct_pivot: float, accepted: float) -> None:
        settings: dict[str, Any] = {
            "direct_pivot": direct_pivot,
            "cutoff": CUTOFF,
            "accepted": accepted,
            "margin_slack": MARGIN_SLACK,
        }
        constraints, rows = model.constraints.constraints, model.constraints.slices
        forms = [_compiled(element, rows) for element in model.forces]
        compiled = [constraint.compiled_rows() for constraint in constraints]
        blocks = [
            block if block is not None else _python_rows(c) for c, block in zip(constraints, compiled, strict=True)
        ]
        elements = [element for element, form in zip(model.forces, forms, strict=True) if form is None]
        in_python = [c for c, block in zip(constraints, compiled, strict=True) if block is None]
        self.python = PythonPart(model, in_python, elements) if in_python or elements else None
        tilt = None if model.scene.tilt is None else model.scene.tilt.compiled_form()
        forms = [form for form in forms if form is not None]
        self.kernel = CoreKernel(
            model.model,
            blocks,
            forms,
            float(term.stiffness),
            term.velocity_gains,
            bool(term.held),
            settings,
            tilt,
            self.python,
            term.inertial,
        )
        self.held = bool(term.held)
        self._zero = np.zeros(model.nv)
        self._zero.flags.writeable = False
        self.unusable = False

    def in_python(self) -> str:
        """What Python evaluates at each evaluation, named (the path's reason says it), or ""."""
        if self.python is None:
            return ""
        parts = [f"constraint(s) {', '.join(b.name for b in self.python.blocks)}"] if self.python.blocks else []
        parts += [f"force(s) {', '.join(e.name for e in self.python.elements)}"] if self.python.elements else []
        return " and ".join(parts) + " evaluated in Python"

    def force(self, model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The applied forces the kernel takes besides its own and its Python part's [N, N m]: none."""
        return self._zero

    def status_counts(self) -> dict[str, int]:
        """The kernel's evaluations by how they were solved (``core cholesky``, ``core pseudo-inverse``, ``core
        pseudo-inverse, not accepted``: solved by the general path instead)."""
        return {f"{self.status} {status}": count for status, count in self.kernel.status_counts.items()}

    @property
    def worst_residual(self) -> float:
        """The largest relative ``|G a - rhs|`` of the evaluations used [-] (the general path's measure)."""
        return self.kernel.worst_residual

    def held_term(self) -> np.ndarray | None:
        """The term the kernel holds over the step, computed at its stage 0 [m/s^2 or rad/s^2], or None (a term not
        held, or a stage-0 evaluation that stopped before its rows: the general path computed that step's)."""
        return self.kernel.held_term()

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        """Joint accelerations [m/s^2, rad/s^2] at (t, q, v) under the applied forces ``tau`` [N, N m] besides the
        compiled elements', at that ``stage`` of a step (0 first: a held term is computed there); check
        :attr:`unusable` before using them."""
        acceleration, usable = self.kernel.acceleration(q, v, tau, t, stage)
        self.unusable = not usable
        return acceleration


class CoreProjector:
    """The projections of :mod:`pinstab.projection` on the core kernel's rows, evaluated in C++
    (``cpp/projection.cpp`` CoreProjection: a kinematics pass, M and the rows of its own, its Python part's rows called
    back): the corrections of ``projection`` and ``post`` take :attr:`compiled` without a Python call.

    Args:
        dynamics: the core evaluation.

    Attributes:
        compiled: the compiled projections (:class:`~pinstab.kernels.CoreProjection`).
    """

    def __init__(self, dynamics: CoreDynamics) -> None:
        self.compiled = CoreProjection(dynamics.kernel, PROJECTION_CUTOFF)

    def position_step(self, q: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        """The Gauss-Newton step and max |phi| [m or rad] at (q, t) (:class:`~pinstab.projection.Projector`)."""
        step, worst, finite = self.compiled.step_at(q, t)
        if not finite:
            raise not_finite()
        return step, worst

    def velocity_projection(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The projected velocity [m/s or rad/s] at (q, t) (:class:`~pinstab.projection.Projector`)."""
        projected, finite = self.compiled.velocities_at(q, v, t)
        if not finite:
            raise not_finite()
        return projected
