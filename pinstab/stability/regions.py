"""Stability functions of Runge-Kutta schemes, explicit and implicit, and the growth per step they give a linear motion.

A Runge-Kutta scheme of tableau (A, b) maps the linear test equation ``y' = lambda y`` to ``y_{k+1} = R(h lambda) y_k``
with the stability function ``R(z) = 1 + z b^T (I - z A)^-1 1`` (E. Hairer and G. Wanner, *Solving Ordinary
Differential Equations II*, section IV.3): a polynomial for an explicit tableau (A strictly lower triangular: the
polynomial of :data:`pinstab.stability.criterion.POLYNOMIALS`), a rational function for an implicit one. Its stability
region is where ``|R(z)| <= 1``; an A-stable scheme's holds the whole left half-plane (implicit Euler, the implicit
midpoint rule).

For the linear motion ``x'' = -K x - D x'`` (the linearization of :mod:`pinstab.stability.modes`, K and D already
divided by the mass) a Runge-Kutta step multiplies the mode of eigenvalue lambda of ``J = [[0, I], [-K, -D]]`` by
``R(h lambda)``. Semi-implicit Euler (velocity first, then the position with the new velocity) is no Runge-Kutta
scheme of the first-order system: its step is the matrix ``[[I - h^2 K, h (I - h D)], [-h K, I - h D]]`` on (x, x'),
the one :func:`pinstab.stability.criterion.amplification` uses for the deviation dynamics.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..errors import PinstabError, choices

SEMI_IMPLICIT_EULER = "semi-implicit-euler"
LIMIT_SCAN = (1e-9, 1e3)  # [s]: the steps :func:`region_limit` searches between


class Tableau(NamedTuple):
    """A Runge-Kutta tableau's coupling A (s x s) and weights b (s,) (the nodes do not enter R)."""

    coupling: np.ndarray
    weights: np.ndarray

    @property
    def explicit(self) -> bool:
        """Whether A is strictly lower triangular (each stage from the ones before it)."""
        return not np.triu(self.coupling).any()


TABLEAUS: dict[str, Tableau] = {}
"""The schemes whose stability function is known, by integrator name (:func:`register_tableau` adds one)."""


def register_tableau(name: str, coupling: object, weights: object) -> None:
    """Make the Runge-Kutta scheme ``name`` known by its tableau: coupling A (s x s), weights b (s,), finite.

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
    TABLEAUS[name] = Tableau(a, b)


register_tableau("euler", [[0.0]], [1.0])
register_tableau("heun", [[0.0, 0.0], [1.0, 0.0]], [0.5, 0.5])
register_tableau(
    "rk4",
    [[0.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
    [1 / 6, 1 / 3, 1 / 3, 1 / 6],
)


def region_schemes() -> list[str]:
    """The schemes whose growth per step is known: the explicit tableaus, semi-implicit Euler, the implicit ones."""
    explicit = [name for name, tableau in TABLEAUS.items() if tableau.explicit]
    return [*explicit, SEMI_IMPLICIT_EULER, *(name for name in TABLEAUS if name not in explicit)]


def _tableau(scheme: str) -> Tableau:
    if scheme not in TABLEAUS:
        raise PinstabError(
            f"no stability function for integrator {scheme!r}; schemes with one: {choices(region_schemes())} "
            "(an integrator's module adds its tableau with pinstab.stability.regions.register_tableau)"
        )
    return TABLEAUS[scheme]


def stability_function(scheme: str, z: complex | np.ndarray) -> np.ndarray:
    """``R(z) = 1 + z b^T (I - z A)^-1 1`` of the registered tableau ``scheme`` at each z = h lambda [-] (complex).

    At a pole of an implicit scheme (``I - z A`` singular) R is infinite.
    """
    a, b = _tableau(scheme)
    values = np.atleast_1d(np.asarray(z, dtype=complex))
    ones, identity = np.ones(len(b), dtype=complex), np.eye(len(b), dtype=complex)
    result = np.empty(values.shape, dtype=complex)
    for index, point in np.ndenumerate(values):
        try:
            result[index] = 1.0 + point * (b @ np.linalg.solve(identity - point * a, ones))
        except np.linalg.LinAlgError:
            result[index] = complex(math.inf, 0.0)
    return result


class StepGrowth(NamedTuple):
    """What one step of a scheme does to the modes of a linear motion.

    Attributes:
        eigenvalues: the motion's eigenvalues lambda [1/s] (of ``[[0, I], [-K, -D]]``).
        moduli: per mode, how much one step multiplies it [-]: ``|R(h lambda)|`` for a Runge-Kutta scheme; for
            semi-implicit Euler the moduli of its step matrix's eigenvalues (in their own order).
        exact: per mode, how much the motion itself multiplies it over the step, ``max(1, exp(h Re lambda))`` [-]: a
            mode that grows on its own (a pendulum above its pivot) is the motion's, not the step's; for
            semi-implicit Euler the largest over the modes.
    """

    eigenvalues: np.ndarray
    moduli: np.ndarray
    exact: np.ndarray

    @property
    def excess(self) -> float:
        """The step's growth beyond the motion's, ``max(moduli / exact)`` [-]: above 1, a mode the motion keeps
        bounded grows with the step (the step is outside the scheme's region for it)."""
        return float(np.max(self.moduli / self.exact, initial=0.0))


def step_growth(scheme: str, step: float, stiffness: np.ndarray, damping: np.ndarray) -> StepGrowth:
    """How a step of ``step`` [s] of ``scheme`` multiplies the modes of ``x'' = -stiffness x - damping x'``
    (f x f each, [1/s^2] and [1/s]: the linearization's K and D divided by the mass).

    Raises:
        PinstabError: a scheme without a registered stability function, naming those with one.
    """
    free = stiffness.shape[0]
    jacobian = np.block([[np.zeros((free, free)), np.eye(free)], [-stiffness, -damping]])
    eigenvalues = np.linalg.eigvals(jacobian)
    with np.errstate(over="ignore"):
        exact = np.maximum(1.0, np.exp(step * eigenvalues.real))
    if scheme == SEMI_IMPLICIT_EULER:
        velocity = np.eye(free) - step * damping
        matrix = np.block([[np.eye(free) - step**2 * stiffness, step * velocity], [-step * stiffness, velocity]])
        moduli = np.abs(np.linalg.eigvals(matrix))
        return StepGrowth(eigenvalues, moduli, np.full(len(moduli), exact.max()))
    return StepGrowth(eigenvalues, np.abs(stability_function(scheme, step * eigenvalues)), exact)


def region_limit(scheme: str, stiffness: np.ndarray, damping: np.ndarray) -> float:
    """The largest step [s] with which ``scheme`` keeps every mode of ``x'' = -stiffness x - damping x'`` inside its
    region (:attr:`StepGrowth.excess` <= 1): the first step of a log scan over :data:`LIMIT_SCAN` that leaves it, then
    bisection; inf when no step of the scan leaves it (an A-stable scheme on a motion that decays), 0 when the
    smallest does."""
    steps = np.geomspace(*LIMIT_SCAN, 400)
    outside = [i for i, h in enumerate(steps) if step_growth(scheme, float(h), stiffness, damping).excess > 1.0]
    if not outside:
        return math.inf
    if outside[0] == 0:
        return 0.0
    low, high = float(steps[outside[0] - 1]), float(steps[outside[0]])
    for _ in range(60):
        middle = math.sqrt(low * high)
        low, high = (middle, high) if step_growth(scheme, middle, stiffness, damping).excess <= 1.0 else (low, middle)
    return low
