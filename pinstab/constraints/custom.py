"""User-defined constraints through the Python API: callables for residual, Jacobian and drift."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ConstraintError
from ..kinematics import Kinematics
from .base import Constraint, RowKind, VelocityTerms

ArrayFn = Callable[..., np.ndarray]


def _checked(name: str, what: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConstraintError(f"constraint {name}: {what} returned {type(value).__name__}, not an array") from None
    if array.shape != shape:
        if array.size == int(np.prod(shape)) and array.ndim <= 1 and len(shape) == 1:
            array = array.reshape(shape)
        else:
            raise ConstraintError(f"constraint {name}: {what} returned shape {array.shape}, expected {shape}")
    if not np.all(np.isfinite(array)):
        raise ConstraintError(f"constraint {name}: {what} returned a non-finite value")
    return array


class HolonomicConstraint(Constraint):
    """``phi(q, t) = 0`` given by callables.

    Args:
        name: unique name.
        rows: number of rows m.
        residual: ``residual(q, t) -> (m,)`` [m or rad].
        jacobian: ``jacobian(q, t) -> (m, nv)``, the derivative of phi along ``pin.integrate``.
        drift: ``drift(q, v, t) -> (m,)``: gamma0 = dG/dt v + d(phi_t)/dt.
        time_derivative: ``time_derivative(q, t) -> (m,)``: partial phi / partial t (rheonomic
            constraints); zero when omitted.
        nv: velocity dimension of the model.
        force_frame: what the multipliers mean, for reports.
        unilateral: ``phi >= 0`` instead of ``phi = 0`` (a joint limit, a gap): the rows enter the
            dynamics as ``G a >= rhs`` with multipliers >= 0 (:class:`RowKind` ``unilateral``).
    """

    holonomic = True

    def __init__(
        self,
        name: str,
        rows: int,
        residual: ArrayFn,
        jacobian: ArrayFn,
        drift: ArrayFn,
        nv: int,
        time_derivative: ArrayFn | None = None,
        force_frame: str = "generalized (user-defined rows)",
        unilateral: bool = False,
    ) -> None:
        self.name, self.rows, self.nv = name, int(rows), int(nv)
        self.row_kind = RowKind.UNILATERAL if unilateral else RowKind.EQUALITY
        self._residual, self._jacobian, self._drift = residual, jacobian, drift
        self._time_derivative = time_derivative
        self.force_frame = force_frame

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return _checked(self.name, "residual", self._residual(q, t), (self.rows,))

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        jac = _checked(self.name, "jacobian", self._jacobian(q, t), (self.rows, self.nv))
        if self._time_derivative is None:
            return VelocityTerms(jac, np.zeros(self.rows))
        return VelocityTerms(jac, _checked(self.name, "time_derivative", self._time_derivative(q, t), (self.rows,)))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return _checked(self.name, "drift", self._drift(q, v, t), (self.rows,))


class PfaffianConstraint(Constraint):
    """``A(q, t) v + b(q, t) = 0`` (nonholonomic) given by callables.

    Args:
        name: unique name.
        rows: number of rows k.
        matrix: ``matrix(q, t) -> (k, nv)``.
        drift: ``drift(q, v, t) -> (k,)``: gamma0 = dA/dt v + db/dt.
        nv: velocity dimension of the model.
        bias: ``bias(q, t) -> (k,)``; zero when omitted.
        force_frame: what the multipliers mean, for reports.
    """

    holonomic = False

    def __init__(
        self,
        name: str,
        rows: int,
        matrix: ArrayFn,
        drift: ArrayFn,
        nv: int,
        bias: ArrayFn | None = None,
        force_frame: str = "generalized (user-defined rows)",
    ) -> None:
        self.name, self.rows, self.nv = name, int(rows), int(nv)
        self._matrix, self._drift, self._bias = matrix, drift, bias
        self.force_frame = force_frame

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        mat = _checked(self.name, "matrix", self._matrix(q, t), (self.rows, self.nv))
        if self._bias is None:
            return VelocityTerms(mat, np.zeros(self.rows))
        return VelocityTerms(mat, _checked(self.name, "bias", self._bias(q, t), (self.rows,)))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return _checked(self.name, "drift", self._drift(q, v, t), (self.rows,))
