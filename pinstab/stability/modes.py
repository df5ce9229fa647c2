"""The stiffest mode of a scene's linearized motion, and the force element it belongs to (issue 37).

At a state (q, v) the motion ``M(q) dv/dt = tau(q, v) - h(q, v)`` linearizes to ``M x'' + D x' + K x = 0`` with
``K = -d(tau - h)/dq`` (on the tangent space, by central differences through ``pin.integrate``) and
``D = -d(tau - h)/dv``; each force element e contributes its own ``K_e``, ``D_e`` and the bias h (gravity, Coriolis)
the rest. The eigenvalues lambda of ``[[0, I], [-M^-1 K, -M^-1 D]]`` are the linearization's; the one of largest
modulus, with its position part x, is the stiffest mode. Its share of element e is
``|x^H (K_e + lambda D_e) x|`` over the sum of those of every element and of the bias: the element whose share is
above :data:`OWNER_SHARE` owns the mode. Its frequency is ``sqrt(x^T K_e x / x^T M x)`` [rad/s] (x real: an
overdamped stiff mode's), and the mode's modal stiffness ``kp = x^T K x / x^T M x`` [1/s^2] and damping
``kd = x^T D x / x^T M x`` [1/s] say whether the motion there decays. The largest stable step of a scheme on the mode
follows from its eigenvalue by the one rule of :func:`pinstab.stability.criterion.mode_step_limit`.

Limit: with constraints the matrices are restricted to the null space of the constraint Jacobian G at q
(``N^T M N``, ``N^T K N``, ``N^T D N``, N an orthonormal basis): the motion's first-order part on the constraint
manifold, without the constraint forces' own derivatives (their curvature times the multipliers).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin
import scipy.linalg

from ..model import ConstrainedModel

DIFFERENCE_STEP = 1e-6  # [rad or m, rad/s or m/s]: central differences of the forces, relative error ~1e-10
OWNER_SHARE = 0.5  # an element owns the stiffest mode when its share of the mode's forces is above this


class StiffMode(NamedTuple):
    """The stiffest mode of the linearization at one state.

    Attributes:
        eigenvalue: its eigenvalue lambda [1/s] (complex for an oscillating mode).
        element: the force element that owns it (its share above :data:`OWNER_SHARE`), or None.
        share: that element's share of the mode's forces (the largest element's when none owns it).
        frequency: the element's frequency on the mode, sqrt(x^T K_e x / x^T M x) [rad/s] (NaN without element).
        stiffness: the mode's modal stiffness kp [1/s^2]. damping: its modal damping kd [1/s].
    """

    eigenvalue: complex
    element: str | None
    share: float
    frequency: float
    stiffness: float
    damping: float

    @property
    def decays(self) -> bool:
        """Whether the mode decays in the linearized motion (kp > 0, kd >= 0): only then is a step that makes it
        grow a step too large (a mode that grows on its own grows with any step)."""
        return self.stiffness > 0 and self.damping >= 0


def _jacobians(
    model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float, acceleration: np.ndarray, split: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """d(force)/dq and d(force)/dv by central differences, stacked per force: the inertia and bias's
    ``-(M a + h)`` at the fixed ``acceleration`` a first (Pinocchio's RNEA), then each element's ``tau_e``
    (shapes (1 + elements, nv, nv)) [N/m or N m/rad, N s/m or N m s/rad]; without ``split``, the elements' sum in
    one row (shapes (2, nv, nv): an element evaluation less per element and difference)."""
    nv, elements = model.nv, list(model.forces)

    def forces(qi: np.ndarray, vi: np.ndarray) -> np.ndarray:
        if split:
            rows = [model.forces_at(qi, vi, t, elements[:1]).copy()] if elements else []  # one kinematics pass
            rows += [model.applied_force(vi, t, [element]).copy() for element in elements[1:]]
        else:
            rows = [model.forces_at(qi, vi, t).copy()]
        inertia = pin.rnea(model.model, model.scratch, qi, vi, acceleration)
        return np.array([-inertia, *rows])

    by_q = np.zeros((1 + (len(elements) if split else 1), nv, nv))
    by_v = np.zeros_like(by_q)
    for i in range(nv):
        step = np.zeros(nv)
        step[i] = DIFFERENCE_STEP
        ahead, behind = pin.integrate(model.model, q, step), pin.integrate(model.model, q, -step)
        by_q[:, :, i] = (forces(ahead, v) - forces(behind, v)) / (2 * DIFFERENCE_STEP)
        by_v[:, :, i] = (forces(q, v + step) - forces(q, v - step)) / (2 * DIFFERENCE_STEP)
    return by_q, by_v


class Linearization(NamedTuple):
    """The linearized motion ``M x'' + D x' + K x = 0`` at one state, on the free coordinates x (module docstring).

    Attributes:
        basis: N, the free motion's orthonormal basis (nv x f; the identity without constraints).
        mass: M = N^T M N [kg, kg m^2]. stiffness: K_f per force, the inertia and bias first, then each element
            (1 + elements, f, f) [N/m or N m/rad]. damping: D_f alike [N s/m or N m s/rad].
        acceleration: the acceleration the inertia's terms are linearized at (nv,) [rad/s^2 or m/s^2].
    """

    basis: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    acceleration: np.ndarray

    def companion(self) -> np.ndarray:
        """``[[0, I], [-M^-1 K, -M^-1 D]]`` (2f x 2f) [1/s^2, 1/s], K and D summed over the forces: its eigenvalues
        are the linearization's [1/s]."""
        free = self.mass.shape[0]
        return np.block(
            [
                [np.zeros((free, free)), np.eye(free)],
                [
                    -np.linalg.solve(self.mass, self.stiffness.sum(axis=0)),
                    -np.linalg.solve(self.mass, self.damping.sum(axis=0)),
                ],
            ]
        )


def linearize(
    model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float, split: bool = True
) -> Linearization | None:
    """The linearized motion at (q, v, t) [rad or m, rad/s or m/s, s], or None when the state is not finite or the
    constraints leave no motion. Without ``split`` the elements are differentiated together (one row of K and D for
    their sum: an element evaluation per difference instead of one per element)."""
    if not (np.isfinite(q).all() and np.isfinite(v).all()):
        return None
    basis = np.eye(model.nv)
    if model.constraints.rows:
        jacobian = model.constraint_values(q, v, t).jacobian
        basis = scipy.linalg.null_space(jacobian)
        if basis.shape[1] == 0:
            return None
    full_mass = model.mass_matrix(q)
    mass = basis.T @ full_mass @ basis
    tau = model.forces_at(q, v, t)  # and h at (q, v) in kin
    acceleration = basis @ np.linalg.solve(mass, basis.T @ (tau - model.kin.bias))
    by_q, by_v = _jacobians(model, q, v, t, acceleration, split=split)
    stiffness = -np.einsum("ia,fij,jb->fab", basis, by_q, basis)  # K_f on the free motion
    damping = -np.einsum("ia,fij,jb->fab", basis, by_v, basis)
    return Linearization(basis, mass, stiffness, damping, acceleration)


def stiffest_mode(
    model: ConstrainedModel, q: np.ndarray, v: np.ndarray, t: float, owner: bool = True
) -> StiffMode | None:
    """The stiffest mode of the linearized motion at (q, v, t) [rad or m, rad/s or m/s, s] (module docstring), or
    None when the state is not finite or the constraints leave no motion. Without ``owner`` the elements are
    differentiated together (their sum: an element evaluation per difference instead of one per element, as the
    stepping loop's checks take it) and the mode has no owner (``element`` None, ``share`` 0, ``frequency`` NaN):
    its eigenvalue, stiffness and damping are the same to rounding."""
    linear = linearize(model, q, v, t, split=owner)
    if linear is None:
        return None
    basis, mass, stiffness, damping, acceleration = linear
    free = basis.shape[1]
    eigenvalues, vectors = np.linalg.eig(linear.companion())
    index = int(np.argmax(np.abs(eigenvalues)))
    eigenvalue, shape = complex(eigenvalues[index]), vectors[:free, index]
    shape = shape / shape[np.argmax(np.abs(shape))]  # real for a real eigenvalue
    contributions = np.abs(np.einsum("i,fij,j->f", shape.conj(), stiffness + eigenvalue * damping, shape))
    shares = contributions / contributions.sum()
    largest = 1 + int(np.argmax(shares[1:])) if owner and len(shares) > 1 else None
    real = shape.real
    modal_mass = real @ mass @ real
    element, frequency = None, float("nan")
    if largest is not None and shares[largest] > OWNER_SHARE:
        element = model.forces[largest - 1].name
        at_rest = -np.einsum(
            "ia,ij,jb->ab", basis, _jacobians(model, q, np.zeros_like(v), t, acceleration)[0][largest], basis
        )
        squares = scipy.linalg.eigh((at_rest + at_rest.T) / 2, mass, eigvals_only=True)
        frequency = float(np.sqrt(max(squares.max(), 0.0)))
    return StiffMode(
        eigenvalue,
        element,
        float(shares[largest]) if largest is not None else 0.0,
        frequency,
        float(real @ stiffness.sum(axis=0) @ real / modal_mass),
        float(real @ damping.sum(axis=0) @ real / modal_mass),
    )
