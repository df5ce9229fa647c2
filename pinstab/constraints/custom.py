"""User-defined constraints through the Python API: callables for residual, Jacobian and drift."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ConstraintError
from ..kinematics import Kinematics
from .base import Constraint, RowKind, VelocityTerms

ArrayFn = Callable[..., np.ndarray]


def _count(value: object, what: str, name: object) -> int:
    """A declared count (``rows``, ``nv``): a whole number >= 1."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ConstraintError(f"constraint {name!r}: {what} must be a whole number >= 1, got {value!r}")
    return int(value)


def _declared(
    name: object, rows: object, nv: object, required: dict[str, object], optional: dict[str, object]
) -> tuple[str, int, int]:
    """(name, rows, nv) of a user constraint, checked with its callables (an optional one may be None)."""
    if not isinstance(name, str) or not name:
        raise ConstraintError(f"a user constraint's name must be a non-empty string, got {name!r}")
    for what, function in [*required.items(), *optional.items()]:
        if not callable(function) and (function is not None or what in required):
            raise ConstraintError(f"constraint {name!r}: {what} must be a callable, got {type(function).__name__}")
    return name, _count(rows, "rows", name), _count(nv, "nv", name)


def _evaluate(name: str, what: str, function: ArrayFn, shape: tuple[int, ...], *args: object) -> np.ndarray:
    """``function(*args)`` checked against ``shape``; an exception it raises becomes a ConstraintError naming
    the constraint and the callable (the original chained as its cause)."""
    try:
        value = function(*args)
    except Exception as exc:
        raise ConstraintError(
            f"constraint {name!r}: the user callable {what}() raised {type(exc).__name__}: {exc}"
        ) from exc
    return _checked(name, what, value, shape)


def _checked(name: str, what: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float array of ``shape`` (a flat one of the right size is reshaped to a vector shape)."""
    try:
        array = np.asarray(value)
    except Exception as exc:
        raise ConstraintError(
            f"constraint {name!r}: {what}() returned {type(value).__name__}, not an array of real numbers ({exc})"
        ) from exc
    if array.dtype.kind not in "biuf":
        raise ConstraintError(
            f"constraint {name!r}: {what}() returned {type(value).__name__} of dtype {array.dtype}, "
            "not an array of real numbers"
        )
    array = array.astype(float)
    if array.shape != shape:
        if array.size == int(np.prod(shape)) and array.ndim <= 1 and len(shape) == 1:
            array = array.reshape(shape)
        else:
            raise ConstraintError(f"constraint {name!r}: {what}() returned shape {array.shape}, expected {shape}")
    if not np.all(np.isfinite(array)):
        raise ConstraintError(f"constraint {name!r}: {what}() returned a non-finite value")
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
        required = {"residual": residual, "jacobian": jacobian, "drift": drift}
        self.name, self.rows, self.nv = _declared(name, rows, nv, required, {"time_derivative": time_derivative})
        self.row_kind = RowKind.UNILATERAL if unilateral else RowKind.EQUALITY
        self._residual, self._jacobian, self._drift = residual, jacobian, drift
        self._time_derivative = time_derivative
        self.force_frame = force_frame

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return _evaluate(self.name, "residual", self._residual, (self.rows,), q, t)

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        jac = _evaluate(self.name, "jacobian", self._jacobian, (self.rows, self.nv), q, t)
        if self._time_derivative is None:
            return VelocityTerms(jac, np.zeros(self.rows))
        return VelocityTerms(jac, _evaluate(self.name, "time_derivative", self._time_derivative, (self.rows,), q, t))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return _evaluate(self.name, "drift", self._drift, (self.rows,), q, v, t)


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
        required = {"matrix": matrix, "drift": drift}
        self.name, self.rows, self.nv = _declared(name, rows, nv, required, {"bias": bias})
        self._matrix, self._drift, self._bias = matrix, drift, bias
        self.force_frame = force_frame

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        mat = _evaluate(self.name, "matrix", self._matrix, (self.rows, self.nv), q, t)
        if self._bias is None:
            return VelocityTerms(mat, np.zeros(self.rows))
        return VelocityTerms(mat, _evaluate(self.name, "bias", self._bias, (self.rows,), q, t))

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return _evaluate(self.name, "drift", self._drift, (self.rows,), q, v, t)
