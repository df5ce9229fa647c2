"""One kinematics pass per state: inertia, bias forces, frame placements, Jacobians, drifts."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from .memory import new_data

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def symmetric_mass_matrix(
    model: pin.Model, data: pin.Data, q: np.ndarray, out: np.ndarray, lower: tuple[np.ndarray, np.ndarray]
) -> np.ndarray:
    """M(q) [kg, kg m^2] into ``out`` (contiguous), lower triangle filled from the upper (crba may fill only
    the upper one); ``lower`` is :func:`mirror_indices` ``(nv)``."""
    return symmetric_copy(pin.crba(model, data, q), out, lower)


def mirror_indices(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The flat indices of the strictly lower triangle of an n x n matrix and of their mirror images in the
    upper one (one flat gather and scatter: a quarter of the cost of the same with 2-D indices)."""
    rows, columns = np.tril_indices(n, -1)
    return np.ravel_multi_index((rows, columns), (n, n)), np.ravel_multi_index((columns, rows), (n, n))


def symmetric_copy(upper: np.ndarray, out: np.ndarray, lower: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """``upper`` into ``out`` (contiguous) with its lower triangle filled from the upper one; ``lower`` is
    :func:`mirror_indices` ``(n)``."""
    out[:] = upper
    flat = out.reshape(-1)
    flat[lower[0]] = flat[lower[1]]
    return out


def with_columns(matrix: np.ndarray, nv: int) -> np.ndarray:
    """A k x nv Jacobian from Pinocchio as a 2-D array (a view): its Python binding hands a matrix of one column
    (one degree of freedom, nv = 1) or of one row back as a 1-D array."""
    return matrix.reshape(-1, nv)


def frame_jacobian(model: pin.Model, data: pin.Data, frame_id: int) -> np.ndarray:
    """6 x nv Jacobian of a frame in LOCAL_WORLD_ALIGNED (linear rows first) [m/rad, 1] from ``data``'s joint
    Jacobians (current after ``computeJointJacobians`` or ``computeAllTerms``)."""
    return with_columns(pin.getFrameJacobian(model, data, frame_id, LWA), model.nv)


class Kinematics:
    """Owns a Pinocchio ``Data`` and updates everything the constraint layer reads, once per state.

    ``q`` is the configuration of the last update (``v`` the velocity of the last full one). After
    :meth:`update`, ``mass_matrix`` [kg, kg m^2] and ``bias`` (h = C v + g) [N, N m] hold the joint-space
    dynamics, and the frame accessors return world-aligned quantities at (q, v) with zero joint
    acceleration (so accelerations are the drift terms). ``stamp`` counts the updates: what is computed
    from one update (:class:`PerUpdate`) is reused until the next.
    """

    def __init__(self, model: pin.Model, data: pin.Data | None = None) -> None:
        self.model = model
        if data is not None:
            self.data = data
        self.mass_matrix = np.zeros((model.nv, model.nv))
        self.bias = np.zeros(model.nv)
        self.lower = mirror_indices(model.nv)
        self.q = pin.neutral(model)
        self.v = np.zeros(model.nv)
        self.stamp = 0
        self._full_stamp = -1  # the stamp of the last full update
        self._gravity_data: pin.Data | None = None  # for g(q) after a partial update

    def __getattr__(self, name: str) -> Any:
        """``data``, the Pinocchio ``Data`` the updates write, is built at first use (a long chain's is costly to build,
        ``benchmarks/data_creation.py``, and a run whose compiled kernel makes every pass never needs it); then it is
        a plain attribute."""
        if name != "data":
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        self.data = new_data(self.model)
        return self.data

    def update(self, q: np.ndarray, v: np.ndarray) -> None:
        """Full pass at (q, v): M, h, placements, Jacobians and zero-acceleration frame motions."""
        model, data = self.model, self.data
        self.q, self.v = q, v
        self.stamp += 1
        # one pass: placements, velocities and accelerations at zero joint acceleration, Jacobians, M, h
        pin.computeAllTerms(model, data, q, v)
        symmetric_copy(data.M, self.mass_matrix, self.lower)
        self.bias[:] = data.nle
        pin.updateFramePlacements(model, data)
        self._full_stamp = self.stamp

    def gravity(self) -> np.ndarray:
        """The generalized gravity g(q) [N, N m] at the last update's q: the full pass's (no pass of its own)
        after :meth:`update`, else one RNEA pass on a second ``Data``. Shared: not to be modified."""
        if self._full_stamp == self.stamp:
            return self.data.g
        if self._gravity_data is None:
            self._gravity_data = new_data(self.model)
        return pin.computeGeneralizedGravity(self.model, self._gravity_data, self.q)

    def update_positions(self, q: np.ndarray) -> None:
        """Placements only (enough for residuals)."""
        self.q = q
        self.stamp += 1
        pin.forwardKinematics(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)

    def update_jacobians(self, q: np.ndarray) -> None:
        """Placements and Jacobians (enough for residuals and constraint Jacobians)."""
        self.q = q
        self.stamp += 1
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)

    def placement(self, frame_id: int) -> pin.SE3:
        """World placement of a frame."""
        return self.data.oMf[frame_id]

    def jacobian(self, frame_id: int) -> np.ndarray:
        """6 x nv frame Jacobian in LOCAL_WORLD_ALIGNED (linear rows first) [m/rad, 1]."""
        return frame_jacobian(self.model, self.data, frame_id)

    def drift_acceleration(self, frame_id: int) -> pin.Motion:
        """Classical acceleration of a frame at zero joint acceleration, LOCAL_WORLD_ALIGNED."""
        return pin.getFrameClassicalAcceleration(self.model, self.data, frame_id, LWA)

    def velocity(self, frame_id: int) -> pin.Motion:
        """Frame velocity, LOCAL_WORLD_ALIGNED [m/s, rad/s]."""
        return pin.getFrameVelocity(self.model, self.data, frame_id, LWA)


class PerUpdate:
    """``compute(kin)`` evaluated once per update of a :class:`Kinematics` (its ``stamp``): a constraint
    block's rows read by the constraint stack, a force element and a controller at the same state are
    computed once. The value is shared: callers must not modify it."""

    def __init__(self, compute: Callable[[Kinematics], Any]) -> None:
        self._compute = compute
        self._kin: Kinematics | None = None
        self._stamp = -1
        self._value: Any = None

    def __call__(self, kin: Kinematics) -> Any:
        if self._kin is not kin or self._stamp != kin.stamp:
            self._value = self._compute(kin)
            self._kin, self._stamp = kin, kin.stamp
        return self._value
