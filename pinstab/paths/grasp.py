"""The grasp path: sticking fingertip contacts with hold torques, evaluated compiled.

A scene whose constraints are all point-row fingertip contacts (``grasp-contact``, ``frictionless`` or
``point-friction``) under a Baumgarte term, and whose force elements have a compiled form
(:meth:`~pinstab.forces.base.ForceElement.compiled_form`: ``grasp-hold``, ``external-force``) or read no kinematics,
needs per evaluation one kinematics pass, the contacts' rows, the holds' least-squares forces and one KKT solve through
Cholesky factors (docs/mathematics.md section 4). The general path makes the same through pinstab's kinematics, a dozen
small NumPy operations per contact and LAPACK calls; the compiled kernel (``cpp/grasp_kernel.cpp``: Pinocchio's
``computeAllTerms``, the rows of ``cpp/contact_terms.cpp``, Eigen's Cholesky factors) makes it in one call. An
evaluation is not used where the general path would leave its direct solve or a hold's least-squares forces (for the
proximal solve or the hold's QP), or where a contact's force leaves its cone: the general path then solves it, or names
the contact in :class:`~pinstab.errors.GraspLostError`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ..constraints import ConstraintSet
from ..constraints.grasp_contacts import FingertipContact
from ..contact.models import MARGIN_SLACK
from ..forces.base import ForceElement
from ..kernels import GraspKernel
from ..model import ConstrainedModel

POINT_MODELS = ("frictionless", "point-friction")  # contact models whose rows are the point's (no rotation rows)
GRASP_FORCE_KINDS = ("hold", "wrench")
"""Compiled force forms the grasp kernel takes."""


def grasp_obstacle(constraints: ConstraintSet, forces: list[ForceElement]) -> str | None:
    """Why the grasp path cannot evaluate these constraints and forces (naming the first it cannot), or None."""
    if not constraints.constraints:
        return "no constraints"
    for constraint in constraints.constraints:
        if not isinstance(constraint, FingertipContact):
            return f"constraint {constraint.name!r} is a {type(constraint).__name__}, not a fingertip contact"
        if constraint.model not in POINT_MODELS:
            models = ", ".join(POINT_MODELS)
            return f"contact {constraint.name!r} is {constraint.model!r}, not a point contact ({models})"
    for element in forces:
        form = element.compiled_form(constraints.slices)
        if form is not None and form["kind"] not in GRASP_FORCE_KINDS:
            form = None
        if element.needs_kinematics and form is None:
            return f"force {element.name!r} ({type(element).__name__}) has no compiled form and reads the kinematics"
    return None


class GraspDynamics:
    """The compiled grasp evaluation (see :func:`grasp_obstacle`).

    Args:
        model: the Pinocchio model. constraints: the scene's constraint stack, all fingertip contacts.
        forces: the scene's force elements. kp: corrector stiffness [1/s^2]. kd: corrector damping [1/s].
        direct_pivot: the general path's direct solve's smallest Delassus pivot (squared) over its largest diagonal
            entry; below it the general path leaves that solve, and the kernel's evaluation is not used.

    Attributes:
        kernel: the compiled evaluation (``cpp/grasp_kernel.cpp``).
        unusable: the last :meth:`acceleration` is not to be used (the general path solves it).
        status: the solver status its solves count under.
    """

    status = "grasp"

    def __init__(
        self,
        model: pin.Model,
        constraints: ConstraintSet,
        forces: list[ForceElement],
        kp: float,
        kd: float,
        direct_pivot: float,
    ) -> None:
        forms = [element.compiled_form(constraints.slices) for element in forces]
        forms = [form if form is not None and form["kind"] in GRASP_FORCE_KINDS else None for form in forms]
        self.kernel = GraspKernel(
            model,
            [_contact_form(contact) for contact in constraints.constraints],
            [form for form in forms if form is not None],
            float(kp),
            float(kd),
            direct_pivot,
            MARGIN_SLACK,
        )
        self._python = [element for element, form in zip(forces, forms, strict=True) if form is None]
        self._zero = np.zeros(model.nv)
        self._zero.flags.writeable = False
        self.unusable = False

    def force(self, model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The applied forces the kernel takes [N, N m]: those of the elements without a compiled form (which read
        no kinematics, :func:`grasp_obstacle`)."""
        if not self._python:
            return self._zero
        return sum((element.generalized_force(model.kin, v, t) for element in self._python), np.zeros(len(v)))

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


def _contact_form(contact: FingertipContact) -> dict[str, Any]:
    return {
        "object_frame": contact.object_frame,
        "finger_frame": contact.finger_frame,
        "components": [int(k) for k in contact.components],
        "mu": float(contact.mu),
    }
