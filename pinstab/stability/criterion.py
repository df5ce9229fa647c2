"""The discrete stability criterion of the deviation dynamics (docs/mathematics.md 3.2-3.3, [M] section 5).

The constraint deviations ``y = (q~, v~)`` (position residual on the m holonomic rows, velocity
residual on all s rows) obey, linearized, ``dy/dt = W y`` with::

    W = [[0, P], [-S, -K]]      P: s -> m picks the holonomic rows of v~

An explicit scheme maps ``y_{k+1} = R(tau W) y_k + rho_k``; the deviations stay bounded when the
spectral radius of R is below one. Besides the four schemes of the docs/mathematics.md table (stabilization term
evaluated at every stage) there is ``held``: a Runge-Kutta step whose stabilization term is evaluated
at the first stage and held over the step. The deviations then see a constant acceleration, which
any scheme of order >= 2 integrates exactly: ``R = [[E - tau^2 P S / 2, tau P - tau^2 P K / 2],
[-tau S, E - tau K]]``, first order ``E - tau K`` on nonholonomic rows.

This module builds W and R, evaluates the radius, places the discrete eigenvalues at a chosen decay
factor per step (automatic gains), and finds the largest stable step for given gains. The Runge-Kutta schemes' R come
from their tableaus (the one registry, :mod:`pinstab.stability.regions`); semi-implicit Euler and ``held`` are the
special ones (:data:`SPECIAL_SCHEMES`). On a linear motion ``x'' = -K x - D x'`` the same R gives the growth per step
of its modes (:func:`step_growth`), and on one mode, by its eigenvalue, the growth and the stability limit of a stiff
mode (:func:`mode_growth`, :func:`mode_step_limit`: the one rule of the stiff-mode watch, ``--integrator auto``, the
stop that names a stiff element, and the element maps).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import NamedTuple

import numpy as np

from ..errors import PinstabError, choices
from . import regions

SPECIAL_SCHEMES = ("semi-implicit-euler", "held")
"""The schemes that are no Runge-Kutta scheme of the first-order system: R is their own step matrix (module
docstring); every other scheme is known by its tableau (:data:`pinstab.stability.regions.TABLEAUS`)."""


def schemes() -> list[str]:
    """The schemes R is known for: the explicit tableaus (euler, heun, rk4, and those an integrator's module registers
    with :func:`pinstab.stability.regions.register_tableau`), the special ones, then the implicit tableaus."""
    explicit = [name for name, tableau in regions.TABLEAUS.items() if tableau.explicit]
    implicit = [name for name, tableau in regions.TABLEAUS.items() if not tableau.explicit]
    return [*explicit, *SPECIAL_SCHEMES, *implicit]


def _polynomial(scheme: str) -> tuple[float, ...] | None:
    """The stability polynomial p of an explicit tableau (lowest degree first: R = p(tau W)), or None."""
    tableau = regions.TABLEAUS.get(scheme)
    return None if tableau is None else tableau.polynomial


def _implicit(scheme: str) -> regions.Tableau | None:
    """The tableau of an implicit scheme registered in :mod:`pinstab.stability.regions` (its R(z) rational), or None:
    its R(tau W) is the tableau's at the matrix tau W."""
    tableau = regions.TABLEAUS.get(scheme)
    return None if tableau is None or tableau.explicit else tableau


def _tableau_amplification(coupling: np.ndarray, weights: np.ndarray, z: np.ndarray) -> np.ndarray:
    """R(Z) = I + (b^T (x) Z) (I - a (x) Z)^-1 (1 (x) I) of a tableau at the matrix Z (n x n)."""
    n, stages = z.shape[0], len(weights)
    stacked = np.linalg.solve(np.eye(stages * n) - np.kron(coupling, z), np.kron(np.ones((stages, 1)), np.eye(n)))
    return np.eye(n) + np.kron(weights[None, :], z) @ stacked


def is_multistage(scheme: str) -> bool:
    """Whether ``scheme`` evaluates the dynamics more than once per step (a Runge-Kutta scheme of
    order >= 2)."""
    return len(_polynomial(scheme) or ()) > 2


def deviation_matrix(stiffness: np.ndarray, damping: np.ndarray, holonomic_mask: np.ndarray) -> np.ndarray:
    """W of the linearized deviation dynamics.

    Args:
        stiffness: S, s x m (rows: all constraint rows; columns: holonomic rows) [1/s^2].
        damping: K, s x s [1/s].
        holonomic_mask: which of the s rows are holonomic (m of them).
    """
    rows = len(holonomic_mask)
    holonomic = int(np.count_nonzero(holonomic_mask))
    pick = np.eye(rows)[holonomic_mask]  # m x s
    return np.block([[np.zeros((holonomic, holonomic)), pick], [-stiffness, -damping]])


@np.errstate(over="ignore", invalid="ignore")
def amplification(
    stiffness: np.ndarray, damping: np.ndarray, holonomic_mask: np.ndarray, step: float, scheme: str
) -> np.ndarray:
    """R(tau W) of one step of ``scheme`` [dimensionless], per the docs/mathematics.md table (huge gains overflow its
    entries to inf or nan, which :func:`spectral_radius` reads as an unbounded radius)."""
    _check_scheme(scheme)
    w = deviation_matrix(stiffness, damping, holonomic_mask)
    n = w.shape[0]
    if scheme in SPECIAL_SCHEMES:
        holonomic = int(np.count_nonzero(holonomic_mask))
        pick = w[:holonomic, holonomic:]
        velocity_map = np.eye(n - holonomic) - step * damping
        if scheme == "held":
            return np.block(
                [
                    [
                        np.eye(holonomic) - 0.5 * step**2 * pick @ stiffness,
                        step * pick - 0.5 * step**2 * pick @ damping,
                    ],
                    [-step * stiffness, velocity_map],
                ]
            )
        return np.block(
            [
                [np.eye(holonomic) - step**2 * pick @ stiffness, step * pick @ velocity_map],
                [-step * stiffness, velocity_map],
            ]
        )
    implicit = _implicit(scheme)
    if implicit is not None:
        return _tableau_amplification(implicit.coupling, implicit.weights, step * w)
    result = np.zeros((n, n))
    power = np.eye(n)
    for coefficient in _polynomial(scheme):
        result += coefficient * power
        power = power @ (step * w)
    return result


def spectral_radius(matrix: np.ndarray) -> float:
    """Largest eigenvalue modulus; inf when ``matrix`` has non-finite entries (R(tau W) overflowed: tau W has
    an eigenvalue beyond the floating-point range of its powers, so the deviations grow without bound)."""
    if matrix.size == 0:
        return 0.0
    if not np.isfinite(matrix).all():
        return math.inf
    return float(np.max(np.abs(np.linalg.eigvals(matrix))))


def deviation_radius(
    stiffness: np.ndarray, damping: np.ndarray, holonomic_mask: np.ndarray, step: float, scheme: str
) -> float:
    """rho(R(tau W)) of the deviation dynamics (S, K, mask; see :func:`amplification`) [dimensionless].

    When S (on the holonomic rows) and K are diagonal the rows do not couple: R(tau W) is block-diagonal
    (a 2 x 2 block per holonomic row, 1 x 1 per other row), and its radius is the largest of the distinct
    rows' :func:`scalar_radius` (Baumgarte's gains: one or two values, instead of an O(s^3) eigenvalue
    solve of a 2s x 2s matrix).
    """
    square = stiffness[holonomic_mask]
    diagonal = np.diag(damping)
    if (
        np.array_equal(damping, np.diag(diagonal))
        and np.array_equal(square, np.diag(np.diag(square)))
        and not stiffness[~holonomic_mask].any()
    ):
        holonomic = set(zip(np.diag(square).tolist(), diagonal[holonomic_mask].tolist(), strict=True))
        first_order = set(diagonal[~holonomic_mask].tolist())
        radii = [scalar_radius(kp, kd, step, scheme) for kp, kd in holonomic]
        radii += [scalar_radius(0.0, kd, step, scheme, holonomic=False) for kd in first_order]
        return max(radii, default=0.0)
    return spectral_radius(amplification(stiffness, damping, holonomic_mask, step, scheme))


def scalar_radius(kp: float, kd: float, step: float, scheme: str, holonomic: bool = True) -> float:
    """rho(R) for scalar gains: S = Kp, K = Kd on a holonomic row (2 x 2), or K = Kd alone.

    From closed forms of R's eigenvalues, not an eigenvalue solve of R: critically damped gains (Kd^2 = 4 Kp, as
    :func:`place_gains` and Kd = 2 sqrt(Kp) give them) make R a Jordan block, whose double eigenvalue a solve of
    the rounded R splits by the square root of the rounding (3.6e-9 on rho at tau Kd = 0.2 for DOPRI5). A
    Runge-Kutta scheme's eigenvalues are p(mu) at the roots mu of mu^2 + tau Kd mu + tau^2 Kp (first order:
    mu = -tau Kd); semi-implicit Euler's and ``held``'s the roots of lambda^2 - t lambda + d, R's trace t and
    determinant d. Each quadratic's discriminant is exact (rational arithmetic on the gains' binary values): a
    double root stays double, a split one is split by its own amount. Non-finite gains: inf, as R's entries.
    """
    _check_scheme(scheme)
    if not (math.isfinite(kp) and math.isfinite(kd) and math.isfinite(step)):
        return math.inf
    try:
        moduli = [abs(value) for value in _scalar_eigenvalues(kp, kd, step, scheme, holonomic)]
    except OverflowError:  # a discriminant beyond the floating-point range: R's own eigenvalue solve
        mask = np.array([holonomic])
        stiffness = np.array([[kp]]) if holonomic else np.zeros((1, 0))
        return spectral_radius(amplification(stiffness, np.array([[kd]]), mask, step, scheme))
    return max(moduli) if all(map(math.isfinite, moduli)) else math.inf  # overflowed: unbounded, as R's entries


def _scalar_eigenvalues(kp: float, kd: float, step: float, scheme: str, holonomic: bool) -> list[complex]:
    """The eigenvalues of R(tau W) for scalar gains (see :func:`scalar_radius`)."""
    tau, stiffness, damping = Fraction(step), Fraction(kp), Fraction(kd)
    if _implicit(scheme) is not None:
        roots = _quadratic_roots(tau * damping, tau * tau * stiffness) if holonomic else [float(-tau * damping)]
        return [complex(value) for value in regions.stability_function(scheme, np.array(roots, dtype=complex))]
    polynomial = _polynomial(scheme)
    if polynomial is not None:
        roots = _quadratic_roots(tau * damping, tau * tau * stiffness) if holonomic else [float(-tau * damping)]
        eigenvalues = []
        for mu in roots:
            value = 0.0
            for coefficient in reversed(polynomial):
                value = value * mu + coefficient
            eigenvalues.append(value)
        return eigenvalues
    if not holonomic:
        return [float(1 - tau * damping)]
    # R of the module docstring and amplification(): semi-implicit Euler [[1 - tau^2 Kp, tau (1 - tau Kd)],
    # [-tau Kp, 1 - tau Kd]], held [[1 - tau^2 Kp / 2, tau - tau^2 Kd / 2], [-tau Kp, 1 - tau Kd]]
    share = Fraction(1, 2) if scheme == "held" else Fraction(1)
    trace = 2 - share * tau * tau * stiffness - tau * damping
    determinant = 1 - tau * damping + (1 - share) * tau * tau * stiffness
    return _quadratic_roots(-trace, determinant)


def _quadratic_roots(linear: Fraction, constant: Fraction) -> list[complex]:
    """The roots of x^2 + linear x + constant (exact coefficients): the discriminant exact, then the larger root
    without cancellation and the other from the product of the two."""
    discriminant = linear * linear - 4 * constant
    if discriminant < 0:
        real, imaginary = -float(linear) / 2, math.sqrt(float(-discriminant)) / 2
        return [complex(real, imaginary), complex(real, -imaginary)]
    larger = -(float(linear) + math.copysign(math.sqrt(float(discriminant)), float(linear))) / 2
    return [larger, float(constant) / larger if larger else 0.0]


@dataclass(frozen=True)
class PlacedGains:
    """Gains that put every discrete eigenvalue at modulus ``decay`` per step.

    Attributes:
        stiffness: S on holonomic rows [1/s^2]. damping: K on holonomic rows [1/s].
        first_order_damping: K on nonholonomic rows [1/s].
        decay: the target r. achieved: rho(R) actually reached (holonomic block).
        first_order_achieved: rho reached on a nonholonomic row (RK4 cannot go below 0.27).
    """

    stiffness: float
    damping: float
    first_order_damping: float
    decay: float
    achieved: float
    first_order_achieved: float


def place_gains(step: float, scheme: str, decay: float) -> PlacedGains:
    """Scalar gains placing the eigenvalues of R(tau W) at ``decay`` (r in [0, 1)).

    Closed forms for the Euler schemes (docs/mathematics.md 3.3) and for ``held`` (trace 2r and determinant
    r^2 of its R give S = (1 - r)^2 / tau^2, K = (1 - r)(3 + r) / (2 tau)). For Heun and RK4, R = p(tau W), so the
    eigenvalues of R are p(mu) for the eigenvalues mu of tau W: choosing mu1, mu2 as two roots of
    p(mu) = r (a real pair or a conjugate pair, the one nearest zero) gives S = mu1 mu2 / tau^2,
    K = -(mu1 + mu2) / tau with both eigenvalues exactly r. A real root may be taken twice (the
    critically damped choice, as in the Euler closed forms); the pair nearest zero, i.e. the gentlest
    gains, is used.
    """
    _check_scheme(scheme)
    if not (0.0 <= decay < 1.0) or not math.isfinite(step) or step <= 0:
        raise PinstabError(
            f"gain placement needs a decay factor r in [0, 1) and a step > 0, got r = {decay}, dt = {step}"
        )
    if _implicit(scheme) is not None:
        raise PinstabError(
            f"the gains are placed for explicit schemes only, not {scheme}: give the gains (--kp, --kd), or use "
            f"another method (baumgarte)"
        )
    if scheme in ("euler", *SPECIAL_SCHEMES):
        stiffness = (1.0 - decay) ** 2 / step**2
        damping = {
            "euler": 2.0 * (1.0 - decay),
            "semi-implicit-euler": 1.0 - decay**2,
            "held": (1.0 - decay) * (3.0 + decay) / 2.0,
        }[scheme] / step
        first_order = (1.0 - decay) / step
    else:
        polynomial = _polynomial(scheme)
        mu_pair = _root_pair(polynomial, decay)
        stiffness = float((mu_pair[0] * mu_pair[1]).real) / step**2
        damping = float(-(mu_pair[0] + mu_pair[1]).real) / step
        first_order = -_real_root_or_minimum(polynomial, decay) / step
    achieved = scalar_radius(stiffness, damping, step, scheme)
    first = scalar_radius(0.0, first_order, step, scheme, holonomic=False)
    return PlacedGains(stiffness, damping, first_order, decay, achieved, first)


def _root_pair(coefficients: tuple[float, ...], decay: float) -> tuple[complex, complex]:
    shifted = np.array(coefficients, dtype=float)
    shifted[0] -= decay
    roots = np.roots(shifted[::-1])
    candidates = []
    for i in range(len(roots)):
        for j in range(i, len(roots)):
            a, b = roots[i], roots[j]
            if i == j and abs(a.imag) > 1e-9:
                continue
            product, total = a * b, a + b
            if abs(product.imag) > 1e-9 or abs(total.imag) > 1e-9 or product.real <= 0 or total.real >= 0:
                continue
            candidates.append((max(abs(a), abs(b)), (a, b)))
    if not candidates:
        raise PinstabError(f"no gains place both eigenvalues at r = {decay}")
    return min(candidates, key=lambda c: c[0])[1]


def _real_root_or_minimum(coefficients: tuple[float, ...], decay: float) -> float:
    """The negative real mu nearest zero with p(mu) = r, else the minimizer of p on the real axis."""
    shifted = np.array(coefficients, dtype=float)
    shifted[0] -= decay
    roots = np.roots(shifted[::-1])
    real = [r.real for r in roots if abs(r.imag) < 1e-9 and r.real < 0]
    if real:
        return max(real)
    derivative = np.polyder(np.array(coefficients[::-1]))
    stationary = [r.real for r in np.roots(derivative) if abs(r.imag) < 1e-9 and r.real < 0]
    return min(stationary, key=lambda mu: np.polyval(np.array(coefficients[::-1]), mu))


def largest_stable_step(
    stiffness: np.ndarray, damping: np.ndarray, holonomic_mask: np.ndarray, scheme: str, upper: float = 10.0
) -> float:
    """The largest tau [s] with rho(R(tau W)) < 1 (scan from small steps, then bisect).

    rho depends on tau^2 S and tau K only, so the same bound says which gains are stable at a given
    step: S (tau_max / tau)^2 and K (tau_max / tau) sit exactly on the boundary. The scan starts at
    1e-9 s, or lower for gains so large that ``tau^2 |S|`` or ``tau |K|`` is not small there.
    """

    def radius(tau: float) -> float:
        return spectral_radius(amplification(stiffness, damping, holonomic_mask, tau, scheme))

    largest_stiffness = float(np.max(np.abs(stiffness), initial=0.0))
    largest_damping = float(np.max(np.abs(damping), initial=0.0))
    if not math.isfinite(largest_stiffness + largest_damping):
        return 0.0  # gains that overflowed: no step is stable
    smallest = min(1e-9, 0.1 / math.sqrt(max(largest_stiffness, 1e-300)), 0.1 / max(largest_damping, 1e-300))
    steps = np.geomspace(smallest, upper, 300)
    unstable = [i for i, tau in enumerate(steps) if radius(tau) >= 1.0]
    if not unstable:
        return upper
    first = unstable[0]
    if first == 0:
        return 0.0
    low, high = steps[first - 1], steps[first]
    for _ in range(60):
        middle = math.sqrt(low * high)
        if radius(middle) < 1.0:
            low = middle
        else:
            high = middle
    return float(low)


class StepGrowth(NamedTuple):
    """What one step of a scheme does to the modes of a linear motion.

    Attributes:
        eigenvalues: the motion's eigenvalues lambda [1/s] (of ``[[0, I], [-K, -D]]``).
        moduli: per mode, how much one step multiplies it [-]: ``|R(h lambda)|`` for a Runge-Kutta scheme; for a
            special scheme (:data:`SPECIAL_SCHEMES`) the moduli of its step matrix's eigenvalues (in their own order).
        exact: per mode, how much the motion itself multiplies it over the step, ``max(1, exp(h Re lambda))`` [-]: a
            mode that grows on its own (a pendulum above its pivot) is the motion's, not the step's; for a special
            scheme the largest over the modes.
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
    (f x f each, [1/s^2] and [1/s]: the linearization's K and D divided by the mass). A Runge-Kutta step multiplies
    the mode of eigenvalue lambda of ``J = [[0, I], [-K, -D]]`` by ``R(h lambda)``; a special scheme's step is its
    matrix of :func:`amplification` on (x, x') (every row holonomic: S = K, K = D).

    Raises:
        PinstabError: an unknown scheme, naming the known ones.
    """
    _check_scheme(scheme)
    free = stiffness.shape[0]
    jacobian = np.block([[np.zeros((free, free)), np.eye(free)], [-stiffness, -damping]])
    eigenvalues = np.linalg.eigvals(jacobian)
    with np.errstate(over="ignore"):
        exact = np.maximum(1.0, np.exp(step * eigenvalues.real))
    if scheme in SPECIAL_SCHEMES:
        matrix = amplification(stiffness, damping, np.ones(free, dtype=bool), step, scheme)
        moduli = np.abs(np.linalg.eigvals(matrix))
        return StepGrowth(eigenvalues, moduli, np.full(len(moduli), exact.max()))
    return StepGrowth(eigenvalues, np.abs(regions.stability_function(scheme, step * eigenvalues)), exact)


def _mode_gains(eigenvalue: complex) -> tuple[float, float, bool]:
    """The scalar gains (Kp, Kd, holonomic) of the mode of ``eigenvalue`` [1/s] alone: ``x' = lambda x`` (Kd =
    -lambda, a first-order row) for a real one, ``x'' = 2 Re(lambda) x' - |lambda|^2 x`` for a complex pair. Unlike a
    mode's modal gains, which carry the slow root of their 2 x 2 reduction too (growing where the motion itself moves
    away: a compressed spring's negative modal stiffness), these give the mode's own growth alone."""
    if eigenvalue.imag == 0:
        return 0.0, -eigenvalue.real, False
    return abs(eigenvalue) ** 2, -2 * eigenvalue.real, True


def mode_growth(eigenvalue: complex, step: float, scheme: str) -> float:
    """``|R|`` [-] of one step of ``step`` [s] of ``scheme`` on the mode of ``eigenvalue`` [1/s]: ``|R(h lambda)|`` of a
    Runge-Kutta scheme, the radius of a special scheme's step matrix on the mode alone (:func:`_mode_gains`), from
    :func:`scalar_radius`'s closed forms.

    Raises:
        PinstabError: an unknown scheme, naming the known ones.
    """
    kp, kd, holonomic = _mode_gains(complex(eigenvalue))
    return scalar_radius(kp, kd, step, scheme, holonomic=holonomic)


MODE_SCAN = (1e-12, 1e6, 32)  # h |lambda| [-] from, to, and points per decade: where mode_step_limit looks for the exit


def mode_step_limit(eigenvalue: complex, scheme: str) -> float:
    """The stability limit of a stiff mode: the largest step h [s] with which ``scheme`` keeps the mode of
    ``eigenvalue`` [1/s] (complex for an oscillating one) from growing, ``mode_growth <= 1`` for every step up to h
    (RK4 on a real lambda: ``2.7853 / |lambda|``; explicit Euler on a pair a +- ib: ``-2a / |lambda|^2``). inf when
    no step makes it grow (an A-stable scheme on a decaying mode); 0 when the smallest does (a mode that grows on its
    own) or the eigenvalue is not finite.

    The steps ``h |lambda|`` of :data:`MODE_SCAN` are scanned from the smallest up to the first at which the mode grows,
    then bisected (60 halvings of the log interval: to the rounding unit).

    Raises:
        PinstabError: an unknown scheme, naming the known ones.
    """
    _check_scheme(scheme)
    eigenvalue = complex(eigenvalue)
    modulus = abs(eigenvalue)
    if not math.isfinite(modulus):
        return 0.0
    if modulus == 0.0:
        return math.inf
    low, high, per_decade = MODE_SCAN
    steps = np.geomspace(low, high, round(per_decade * math.log10(high / low)) + 1) / modulus
    exit_index = next((i for i, h in enumerate(steps) if mode_growth(eigenvalue, float(h), scheme) > 1.0), None)
    if exit_index is None:
        return math.inf
    if exit_index == 0:
        return 0.0
    inside, outside = float(steps[exit_index - 1]), float(steps[exit_index])
    for _ in range(60):
        middle = math.sqrt(inside * outside)
        if mode_growth(eigenvalue, middle, scheme) > 1.0:
            outside = middle
        else:
            inside = middle
    return inside


def _check_scheme(scheme: str) -> None:
    if scheme not in SPECIAL_SCHEMES and scheme not in regions.TABLEAUS:
        raise PinstabError(f"unknown integrator {scheme!r}; valid integrators: {choices(schemes())}")
