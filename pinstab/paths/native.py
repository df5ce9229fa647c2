"""The native path: Pinocchio's own ``constraintDynamics`` evaluates a scene's accelerations.

A scene whose constraints are all ``point`` or ``planar-point`` closures (``planar-point`` only on a
planar mechanism, where the out-of-plane row is identically redundant) and whose stabilization term
is Baumgarte's (``none``, ``baumgarte``, kinematic ``mukharlyamov``, ``projection``, ``post``) can be
evaluated by one call into Pinocchio: its sparse constrained Cholesky with the corrector
``-Kp phi - Kd G v`` (Kp [1/s^2], Kd [1/s]). No pinstab kinematics pass and no per-closure Python.

Pinocchio's proximal solve can lose the constraints at a singular configuration without saying so
(its own residual is measured on its factorization), so :meth:`NativeDynamics.residual` checks a
solve from scratch: the constraint Jacobian, the contact points and their drift accelerations give
``G a - rhs``. That check reads every closure, so the stepping loop runs it at the start and at its
periodic checks, and on every evaluation while a check has failed recently (see
:mod:`pinstab.simulate`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from ..constraints import Constraint, FrameClosure, RowKind
from ..forces.base import ForceElement
from ..kernels import NativeKernel, native_residual
from ..kinematics import LWA, with_columns
from ..memory import new_data
from .banded import joint_supports

CONTACT_TYPES = {
    "point": pin.ContactType.CONTACT_3D,
    "planar-point": pin.ContactType.CONTACT_3D,
    "weld": pin.ContactType.CONTACT_6D,
}
"""Closure kinds Pinocchio's algorithm takes, as contacts in world axes."""
NATIVE_KINDS = ("point", "planar-point")
"""Closure kinds of the native path (a weld's rotation rows and moment axes differ from pinstab's)."""

NATIVE_FORCE_KINDS = ("joint-spring", "wrench", "spring-damper", "joint-torque")
"""Compiled force forms the native kernel takes (``cpp/force_elements.hpp``: a hold's torques read the core's rows)."""

PLANAR_TOLERANCE = 1e-12  # [m per rad]: out-of-plane Jacobian entries of a planar mechanism's closure


def rigid_constraint(model: pin.Model, closure: FrameClosure, kp: float, kd: float) -> pin.RigidConstraintModel:
    """Pinocchio's model of a closure: a 3-D (point-like) or 6-D (weld) contact between frame a and
    frame b (or the world), in LOCAL_WORLD_ALIGNED, with the corrector (Kp [1/s^2], Kd [1/s])."""
    (joint_a, placement_a), (joint_b, placement_b) = closure.sides(model)
    rcm = pin.RigidConstraintModel(CONTACT_TYPES[closure.kind], model, joint_a, placement_a, joint_b, placement_b, LWA)
    rcm.name = closure.name
    rcm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(float(kp), float(kd)))
    return rcm


def native_forces(elements: list[ForceElement], rows: Mapping[str, slice]) -> tuple[list[dict[str, Any]], str | None]:
    """The elements' compiled forms (in order) when the native kernel takes every one, else no forms and why, naming
    the first element it does not take (evaluated in Python then); ``rows``: each constraint's rows by name."""
    forms = []
    for element in elements:
        form = element.compiled_form(rows)
        if form is None or form["kind"] not in NATIVE_FORCE_KINDS:
            what = "no compiled form" if form is None else f"the compiled form {form['kind']}"
            return [], (
                f"force element {element.name!r} has {what} (the native kernel takes {', '.join(NATIVE_FORCE_KINDS)})"
            )
        forms.append(form)
    return forms, None


def unsupported_constraint(constraints: list[Constraint], kinds: tuple[str, ...] = tuple(CONTACT_TYPES)) -> str | None:
    """Why these constraints cannot run on Pinocchio's algorithm with closures of ``kinds`` (naming the
    first that cannot), or None."""
    for constraint in constraints:
        if not isinstance(constraint, FrameClosure):
            return f"constraint {constraint.name!r} is a {type(constraint).__name__}, not a frame closure"
        if constraint.prescribed:
            return f"constraint {constraint.name!r} is prescribed (a servo: the controls realize it)"
        if constraint.row_kind != RowKind.EQUALITY:
            return f"constraint {constraint.name!r} has {constraint.row_kind.value} rows (Pinocchio's take equalities)"
        if constraint.kind not in kinds:
            return f"constraint {constraint.name!r} is a {constraint.kind} closure, not one of {', '.join(kinds)}"
    return None


def non_planar_closure(model: pin.Model, data: pin.Data, closures: list[FrameClosure], q: np.ndarray) -> str | None:
    """The first ``planar-point`` closure whose out-of-plane motion the joints do not block at q (so
    it has no 3-D contact equivalent), or None; ``data``: a ``Data`` of the model to compute in.

    The out-of-plane row n . (J_a - J_b) of every such closure at once from the joints' world Jacobian: a point p
    carried by joint j moves by J_lin - p x J_ang over the columns that move j (Pinocchio's frame Jacobian in
    LOCAL_WORLD_ALIGNED), i.e. n . J_lin - (n x p) . J_ang."""
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    planar = [closure for closure in closures if closure.kind == "planar-point"]
    if not planar:
        return None
    in_plane = np.array([closure.selection for closure in planar])
    normals = np.cross(in_plane[:, 0], in_plane[:, 1])
    jacobian = with_columns(data.J, model.nv)
    supports = joint_supports(model)
    out_of_plane = np.zeros((len(planar), model.nv))
    for sign, frames in ((1.0, [c.frame_a for c in planar]), (-1.0, [c.frame_b for c in planar])):
        carried = [index for index, frame in enumerate(frames) if frame is not None]
        joints = [model.frames[frames[index]].parentJoint for index in carried]
        points = np.array([data.oMf[frames[index]].translation for index in carried]).reshape(-1, 3)
        moved = normals[carried] @ jacobian[:3] - np.cross(normals[carried], points) @ jacobian[3:]
        out_of_plane[carried] += sign * np.where(supports[joints], moved, 0.0)
    moving = np.abs(out_of_plane).max(axis=1, initial=0.0) > PLANAR_TOLERANCE
    return planar[int(np.argmax(moving))].name if moving.any() else None


class _Constraints(NamedTuple):
    """Pinocchio's side of a :class:`NativeDynamics`: its constraint models and data and the proximal settings."""

    models: pin.StdVec_RigidConstraintModel
    datas: pin.StdVec_RigidConstraintData
    settings: pin.ProximalSettings


class NativeDynamics:
    """Pinocchio's ``constraintDynamics`` for frame closures with its Baumgarte corrector.

    Pinocchio's constraint models of the closures (:attr:`models`, :attr:`datas`, :attr:`settings`) are built at
    their first use, not here: the banded path keeps this solve for the evaluations its LU finds singular, which
    most runs never meet.

    Args:
        model: the Pinocchio model.
        closures: frame closures (see :func:`unsupported_constraint`); :meth:`multipliers` and
            :meth:`residual` take point and planar-point closures only.
        kp: corrector stiffness [1/s^2]. kd: corrector damping [1/s].
        mu: proximal regularization of Pinocchio's solve [-], or a function giving it, called once when the
            constraint models are built.
        data: a ``Data`` of the model to solve in (shared with other computations: each solve recomputes all it
            reads, and :meth:`multipliers` / :meth:`residual` must follow their solve), or None for its own; a
            ``Data`` of a long chain is costly (``benchmarks/data_creation.py``).

    Attributes:
        rows: selection from Pinocchio's contact rows to the closures' rows.
        forces: the force elements' compiled forms the compiled kernel adds to the applied forces it is given
            (:meth:`set_forces`; none by default).
        force_obstacle: why the compiled kernel does not take the scene's force elements (:func:`native_forces`),
            or None.
    """

    def __init__(
        self,
        model: pin.Model,
        closures: list[FrameClosure],
        kp: float = 0.0,
        kd: float = 0.0,
        mu: float | Callable[[], float] = 1e-12,
        data: pin.Data | None = None,
    ) -> None:
        self.model = model
        self.data = new_data(model) if data is None else data
        self.closures = closures
        self.kp, self.kd = float(kp), float(kd)
        self._corrector = (self.kp, self.kd)  # the gains of Pinocchio's corrector (set_gains)
        self._mu = mu
        widths = [6 if closure.kind == "weld" else 3 for closure in closures]
        self.rows = np.zeros((sum(c.rows for c in closures), sum(widths)))
        row = column = 0
        for closure, width in zip(closures, widths, strict=True):
            block = np.eye(6) if width == 6 else closure.selection
            self.rows[row : row + closure.rows, column : column + width] = block
            row, column = row + closure.rows, column + width
        self._kernel: NativeKernel | None = None
        self.forces: list[dict[str, Any]] = []
        self.force_obstacle: str | None = None

    @cached_property
    def _pinocchio(self) -> _Constraints:
        """Pinocchio's constraint models and data of the closures and the solve's settings, built (and the data
        initialized for them) at first use."""
        models, datas = pin.StdVec_RigidConstraintModel(), pin.StdVec_RigidConstraintData()
        for closure in self.closures:
            models.append(rigid_constraint(self.model, closure, *self._corrector))
        for rcm in models:
            datas.append(rcm.createData())
        pin.initConstraintDynamics(self.model, self.data, models, datas)
        mu = self._mu() if callable(self._mu) else self._mu
        return _Constraints(models, datas, pin.ProximalSettings(1e-14, 1e-12, mu, 50))

    @property
    def models(self) -> pin.StdVec_RigidConstraintModel:
        """Pinocchio's models of the closures (:func:`rigid_constraint`)."""
        return self._pinocchio.models

    @property
    def datas(self) -> pin.StdVec_RigidConstraintData:
        """Their data."""
        return self._pinocchio.datas

    @property
    def settings(self) -> pin.ProximalSettings:
        """The proximal solve's settings (accuracies 1e-14 absolute and 1e-12 relative, mu, 50 iterations)."""
        return self._pinocchio.settings

    def set_forces(self, elements: list[ForceElement], rows: Mapping[str, slice]) -> None:
        """Give the compiled kernel the force elements (``rows``: each constraint's rows by name): their compiled
        forms where it takes every one, else none, and :attr:`force_obstacle` says why (:func:`native_forces`)."""
        self.forces, self.force_obstacle = native_forces(elements, rows)
        self._kernel = None

    def kernel(self) -> NativeKernel:
        """The same solve compiled (``cpp/native_kernel.cpp``) under the applied forces it is given plus
        :attr:`forces`, for the compiled step loop; built on first use."""
        if self._kernel is None:
            models = list(self.models)
            self._kernel = NativeKernel(
                self.model,
                [rcm.joint1_id for rcm in models],
                [rcm.joint1_placement.homogeneous for rcm in models],
                [rcm.joint2_id for rcm in models],
                [rcm.joint2_placement.homogeneous for rcm in models],
                self.kp,
                self.kd,
                self.settings.absolute_accuracy,
                self.settings.relative_accuracy,
                self.settings.mu,
                self.settings.max_iter,
                self.forces,
            )
        return self._kernel

    def set_gains(self, kp: float, kd: float) -> None:
        """Set the corrector's Kp [1/s^2] and Kd [1/s] on every closure."""
        self.kp, self.kd = float(kp), float(kd)
        self._corrector = (self.kp, self.kd)
        self._kernel = None
        if "_pinocchio" in self.__dict__:  # built
            for rcm in self._pinocchio.models:
                rcm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(self.kp, self.kd))

    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Joint accelerations [m/s^2, rad/s^2] at (q, v) under the applied forces ``tau`` [N, N m]."""
        built = self._pinocchio
        return pin.constraintDynamics(self.model, self.data, q, v, tau, built.models, built.datas, built.settings)

    def multipliers(self) -> np.ndarray:
        """The closures' multipliers [N] of the last :meth:`acceleration`, in pinstab's rows (force on a)."""
        return self.rows @ self.data.lambda_c

    def residual(self, v: np.ndarray, acceleration: np.ndarray) -> float:
        """How far the last :meth:`acceleration` misses ``G a + gamma0 = -Kp phi - Kd G v``, relative to
        the size of its terms (Euclidean norms): :func:`pinstab.kernels.primal_residual` without the free force's
        scale (the solve's tau is not at hand), ``|G a - rhs| / (|rhs| + |G|_F |a|)`` [-], from Pinocchio's data
        after the solve: its constraint Jacobian, contact points and drifts (``cpp/native_kernel.cpp``, the compiled
        kernel's too)."""
        built = self._pinocchio
        return native_residual(
            self.model, self.data, built.models, built.datas, self.rows, self.kp, self.kd, v, acceleration
        )


class NativeProjector:
    """The M-weighted projections of :mod:`pinstab.projection` with Pinocchio's algorithms, for the
    closures of the native path.

    The position step is one ``constraintDynamics`` call on a gravity-free copy of the model at zero
    velocity and zero force with the corrector Kp = 1, Kd = 0: the free acceleration and the drift
    vanish, so the solution is ``a = argmin |a|_M subject to G a = -phi``, i.e. the Gauss-Newton step
    ``-M^-1 G^T (G M^-1 G^T)^-1 phi``, and ``phi = -G a`` is read from it with Pinocchio's constraint
    Jacobian. The velocity projection reuses that call's factorization of the KKT matrix
    ``[[-mu I, G], [G^T, M]]``: solving it for ``(G v, 0)`` gives ``M^-1 G^T (G M^-1 G^T)^-1 G v``.
    (``impulseDynamics`` is not used: it ignores the second body of a closure between two bodies.)

    Args:
        model: the Pinocchio model. closures: point and planar-point closures.
    """

    def __init__(self, model: pin.Model, closures: list[FrameClosure]) -> None:
        free = pin.Model(model)
        free.gravity = pin.Motion.Zero()
        self.dynamics = NativeDynamics(free, closures, kp=1.0, kd=0.0)
        self._zero = np.zeros(model.nv)
        self._rhs = np.zeros(self.dynamics.rows.shape[1] + model.nv)
        self._factored: np.ndarray | None = None  # the configuration of the last factorization
        self._jacobian = np.zeros((self.dynamics.rows.shape[1], model.nv))

    def position_step(self, q: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        dynamics = self.dynamics
        step = dynamics.acceleration(q, self._zero, self._zero)
        self._factored = q
        jacobian = pin.getConstraintsJacobian(dynamics.model, dynamics.data, dynamics.models, dynamics.datas)
        self._jacobian = with_columns(jacobian, dynamics.model.nv)
        phi = dynamics.rows @ (self._jacobian @ step)  # = -phi
        return step, float(np.max(np.abs(phi), initial=0.0))

    def velocity_projection(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        if self._factored is not q and not np.array_equal(self._factored, q):
            self.position_step(q, t)
        rhs = self._rhs
        rows = len(rhs) - len(v)
        rhs[:rows] = self._jacobian @ v
        return v - self.dynamics.data.constraint_chol.solve(rhs)[rows:]
