"""Stability functions of Runge-Kutta schemes, explicit and implicit: the one registry of the schemes' tableaus.

A Runge-Kutta scheme of tableau (A, b) maps the linear test equation ``y' = lambda y`` to ``y_{k+1} = R(h lambda) y_k``
with the stability function ``R(z) = 1 + z b^T (I - z A)^-1 1`` (E. Hairer and G. Wanner, *Solving Ordinary
Differential Equations II*, section IV.3): a polynomial for an explicit tableau (A strictly lower triangular: its
coefficients 1, then b^T A^(k-1) 1, :func:`stability_polynomial`), a rational function for an implicit one. Its
stability region is where ``|R(z)| <= 1``; an A-stable scheme's holds the whole left half-plane (implicit Euler, the
implicit midpoint rule).

Every scheme whose stability function is known is registered here by its tableau (:func:`register_tableau`: euler,
heun and rk4 below, an integrator's module its own); the schemes that are no Runge-Kutta scheme of the first-order
system (semi-implicit Euler, a step with its stabilization term held) and the growth per step of a mode are
:mod:`pinstab.stability.criterion`'s.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from ..errors import PinstabError, choices


class Tableau(NamedTuple):
    """A Runge-Kutta tableau's coupling A (s x s) and weights b (s,) (the nodes do not enter R), and for an explicit
    one its stability polynomial (:func:`stability_polynomial`; None for an implicit one)."""

    coupling: np.ndarray
    weights: np.ndarray
    polynomial: tuple[float, ...] | None

    @property
    def explicit(self) -> bool:
        """Whether A is strictly lower triangular (each stage from the ones before it)."""
        return self.polynomial is not None


def stability_polynomial(coupling: np.ndarray, weights: np.ndarray) -> tuple[float, ...]:
    """The coefficients of an explicit tableau's stability polynomial, lowest degree first: 1, then b^T A^(k-1) 1 for
    k = 1 .. s, each the correctly rounded value of the tableau's binary entries (rational arithmetic: RK4's
    ``b^T 1`` is 1, where a floating-point sum of 1/6 + 1/3 + 1/3 + 1/6 gives 1 - 2^-53)."""
    a = [[Fraction(float(value)) for value in row] for row in np.asarray(coupling)]
    b = [Fraction(float(value)) for value in np.asarray(weights)]
    column = [Fraction(1)] * len(b)  # A^(k-1) 1
    coefficients = [1.0]
    for _ in b:
        coefficients.append(float(sum(bi * ci for bi, ci in zip(b, column, strict=True))))
        column = [sum(aij * cj for aij, cj in zip(row, column, strict=True)) for row in a]
    return tuple(coefficients)


TABLEAUS: dict[str, Tableau] = {}
"""The schemes whose stability function is known, by integrator name (:func:`register_tableau` adds one)."""


def register_tableau(name: str, coupling: object, weights: object) -> None:
    """Make the Runge-Kutta scheme ``name`` known by its tableau: coupling A (s x s), weights b (s,), finite (an
    explicit one with its stability polynomial).

    Raises:
        PinstabError: shapes that do not match, or non-finite entries (naming the scheme).
    """
    a = np.atleast_2d(np.asarray(coupling, dtype=float))
    b = np.atleast_1d(np.asarray(weights, dtype=float))
    stages = b.shape[0]
    if b.ndim != 1 or a.shape != (stages, stages) or not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise PinstabError(
            f"tableau of {name!r}: the coupling must be a finite s x s matrix and the weights s finite numbers, got "
            f"shapes {a.shape} and {b.shape}"
        )
    TABLEAUS[name] = Tableau(a, b, None if np.triu(a).any() else stability_polynomial(a, b))


register_tableau("euler", [[0.0]], [1.0])
register_tableau("heun", [[0.0, 0.0], [1.0, 0.0]], [0.5, 0.5])
register_tableau(
    "rk4",
    [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
    [1 / 6, 1 / 3, 1 / 3, 1 / 6],
)


def _tableau(scheme: str) -> Tableau:
    if scheme not in TABLEAUS:
        raise PinstabError(
            f"no stability function for integrator {scheme!r}; tableaus registered: {choices(TABLEAUS)} "
            "(an integrator's module adds its tableau with pinstab.stability.regions.register_tableau)"
        )
    return TABLEAUS[scheme]


def stability_function(scheme: str, z: complex | np.ndarray) -> np.ndarray:
    """``R(z) = 1 + z b^T (I - z A)^-1 1`` of the registered tableau ``scheme`` at each z = h lambda [-] (complex).

    At a pole of an implicit scheme (``I - z A`` singular) R is infinite.
    """
    a, b, _ = _tableau(scheme)
    values = np.atleast_1d(np.asarray(z, dtype=complex))
    ones, identity = np.ones(len(b), dtype=complex), np.eye(len(b), dtype=complex)
    result = np.empty(values.shape, dtype=complex)
    for index, point in np.ndenumerate(values):
        try:
            result[index] = 1.0 + point * (b @ np.linalg.solve(identity - point * a, ones))
        except np.linalg.LinAlgError:
            result[index] = complex(math.inf, 0.0)
    return result
