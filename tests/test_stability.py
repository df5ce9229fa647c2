"""The discrete criterion: amplification matrices against the schemes written out by hand, gain
placement, stable-step bounds, and the criterion's predictions against real runs."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from pinstab.errors import PinstabError
from pinstab.stability import regions
from pinstab.stability.criterion import (
    SPECIAL_SCHEMES,
    amplification,
    deviation_radius,
    largest_stable_step,
    mode_growth,
    mode_step_limit,
    place_gains,
    scalar_radius,
    schemes,
    spectral_radius,
)

SCHEMES = [name for name in schemes() if name in SPECIAL_SCHEMES or regions.TABLEAUS[name].explicit]
"""The explicit schemes (the specials and the explicit tableaus: euler, heun, rk4, dop853, dopri5)."""


def one_step(scheme, stiffness, damping, step, y):
    """One step of the deviation ODE  y' = v, v' = -S y - K v  (scalar), written out per scheme."""

    def rate(state):
        position, velocity = state
        return np.array([velocity, -stiffness * position - damping * velocity])

    if scheme == "euler":
        return y + step * rate(y)
    if scheme == "semi-implicit-euler":
        velocity = y[1] + step * (-stiffness * y[0] - damping * y[1])
        return np.array([y[0] + step * velocity, velocity])
    if scheme == "heun":
        k1 = rate(y)
        k2 = rate(y + step * k1)
        return y + step / 2 * (k1 + k2)
    if scheme in ("dop853", "dopri5"):  # the tableau stage by stage (the criterion uses its stability polynomial)
        from pinstab.integration import INTEGRATORS

        tableau = INTEGRATORS.entry(scheme).factory

        slopes = []
        for stage in range(tableau.stages):
            slopes.append(
                rate(y + step * sum(c * k for c, k in zip(tableau.coupling[stage, :stage], slopes, strict=True)))
            )
        return y + step * sum(b * k for b, k in zip(tableau.weights, slopes, strict=True))
    if scheme == "rk4":
        k1 = rate(y)
        k2 = rate(y + step / 2 * k1)
        k3 = rate(y + step / 2 * k2)
        k4 = rate(y + step * k3)
        return y + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    # held: the acceleration of the first stage, held over the step and integrated exactly
    acceleration = -stiffness * y[0] - damping * y[1]
    return np.array([y[0] + step * y[1] + step**2 / 2 * acceleration, y[1] + step * acceleration])


@pytest.mark.parametrize("scheme", SCHEMES)
def test_amplification_matches_the_scheme_written_out(scheme):
    rng = np.random.default_rng(1)
    mask = np.array([True])
    for _ in range(5):
        stiffness, damping, step = 10 ** rng.uniform(0, 6), 10 ** rng.uniform(0, 3), 10 ** rng.uniform(-4, -2)
        y = rng.standard_normal(2)
        matrix = amplification(np.array([[stiffness]]), np.array([[damping]]), mask, step, scheme)
        np.testing.assert_allclose(matrix @ y, one_step(scheme, stiffness, damping, step, y), rtol=1e-12, atol=1e-12)


def test_amplification_with_a_nonholonomic_row_is_first_order():
    """One holonomic and one nonholonomic row, coupled through K: the nonholonomic deviation has no
    position part, so R is 3 x 3 and its last row is the first-order update."""
    stiffness = np.array([[400.0], [0.0]])
    damping = np.array([[40.0, 5.0], [3.0, 30.0]])
    matrix = amplification(stiffness, damping, np.array([True, False]), 1e-3, "euler")
    expected = np.eye(3) + 1e-3 * np.array([[0, 1, 0], [-400, -40, -5], [0, -3, -30]])
    np.testing.assert_allclose(matrix, expected, rtol=1e-14)


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("decay", [0.0, 0.2, 0.5, 0.9])
def test_placed_gains_put_every_eigenvalue_at_the_decay_factor(scheme, decay):
    placed = place_gains(2e-3, scheme, decay)
    # the placed gains are rounded: the exact double root r of R splits by the square root of that rounding (1e-8)
    assert placed.achieved == pytest.approx(decay, abs=1e-7)
    assert placed.stiffness > 0 and placed.damping > 0
    # a first-order row sees p(mu) on the real axis, which Heun keeps >= 1/2, RK4 >= 0.27039, DOPRI5 >= 0.17315
    floor = {"heun": 0.5, "rk4": 0.27039, "dopri5": 0.17315}.get(scheme, 0.0)
    assert placed.first_order_achieved == pytest.approx(max(decay, floor), abs=1e-4)


def test_euler_closed_forms_of_math_md():
    tau, r = 1e-3, 0.3
    explicit, symplectic = place_gains(tau, "euler", r), place_gains(tau, "semi-implicit-euler", r)
    assert explicit.damping == pytest.approx(2 * (1 - r) / tau) and explicit.stiffness == pytest.approx(
        (1 - r) ** 2 / tau**2
    )
    assert symplectic.damping == pytest.approx((1 - r**2) / tau) and symplectic.stiffness == pytest.approx(
        (1 - r) ** 2 / tau**2
    )


def test_baumgarte_semi_implicit_boundary_is_two_alpha_tau_equals_two():
    """det R = 1 - tau Kd for semi-implicit Euler (docs/mathematics.md 3.3): Kd tau = 2 is the boundary."""
    assert scalar_radius(1e6, 2e3, 1e-3, "semi-implicit-euler") > 1.0
    bound = largest_stable_step(np.array([[1e6]]), np.array([[2e3]]), np.array([True]), "semi-implicit-euler")
    assert (
        scalar_radius(1e6, 2e3, 0.999 * bound, "semi-implicit-euler")
        < 1.0
        <= scalar_radius(1e6, 2e3, 1.001 * bound, "semi-implicit-euler")
    )
    # with Kp = 1e6 the trace condition binds first: 2 - tau^2 Kp - tau Kd = -(1 + det), tau = 2 (sqrt 2 - 1) / 1e3
    assert bound == pytest.approx(2 * (np.sqrt(2) - 1) * 1e-3, rel=1e-9)


def test_spectral_radius_of_empty_matrix_is_zero():
    assert spectral_radius(np.zeros((0, 0))) == 0.0


def test_gains_that_overflow_r_have_an_unbounded_radius_and_a_scaled_bound():
    """Kp = 1e308 overflows R(tau W) at dt = 1e-3: rho is inf, not a LinAlgError; the stable step still
    follows the scaling (S c^2, K c) -> tau / c down to such gains."""
    mask = np.array([True])
    assert scalar_radius(1e308, 20.0, 1e-3, "rk4") == np.inf
    assert spectral_radius(np.array([[np.nan, 0.0], [0.0, 1.0]])) == np.inf
    unit = largest_stable_step(np.array([[1.0]]), np.array([[2.0]]), mask, "rk4")
    huge = largest_stable_step(np.array([[1e300]]), np.array([[2e150]]), mask, "rk4")
    assert huge == pytest.approx(unit / 1e150, rel=1e-6)
    assert largest_stable_step(np.array([[np.inf]]), np.array([[1.0]]), mask, "rk4") == 0.0


def test_stability_map_agrees_with_the_criterion(tmp_path):
    """A small map on the four-bar: prediction and observation agree on most cells, both regions occur,
    and the PNG and JSON are written."""

    import pinstab
    from pinstab.analysis.stability_map import plot_stability_map, stability_map
    from pinstab.cli import main

    result = stability_map(pinstab.load_scene("fourbar"), integrator="semi-implicit-euler", grid=8, steps=100)
    assert result.agreement >= 0.9
    observed = {c.observed for c in result.cells}
    assert {"converged", "diverged"} <= observed
    png = plot_stability_map(result, tmp_path / "map.png")
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert (
        main(
            ["stability", "fourbar", "--grid", "3", "--steps", "50", "--json", "--quiet", "-o", str(tmp_path / "m.png")]
        )
        == 0
    )


def test_stability_map_refuses_bad_ranges():
    import pinstab
    from pinstab.analysis.stability_map import stability_map

    with pytest.raises(pinstab.PinstabError, match="dt range must be two increasing positive numbers"):
        stability_map(pinstab.load_scene("fourbar"), dt_range=(1e-2, 1e-3))
    with pytest.raises(pinstab.PinstabError, match="stability maps take methods"):
        stability_map(pinstab.load_scene("fourbar"), method="projection")


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"grid": 201}, "grid must be a whole number from 2 to 200, got 201"),
        ({"grid": 2.5}, "grid must be a whole number"),
        ({"steps": 1}, "steps must be a whole number at least 2, got 1"),
        ({"grid": 200, "steps": 1000}, "40,000,000 steps, more than the 20,000,000 a map takes"),
        ({"perturbation": 0.0}, "perturbation must be a number above 0 and at most 1"),
        ({"perturbation": float("nan")}, "got nan"),
        ({"perturbation": 1.5}, "got 1.5"),
    ],
)
def test_stability_map_refuses_arguments_out_of_range(options, message):
    import pinstab
    from pinstab.analysis.stability_map import stability_map

    with pytest.raises(pinstab.PinstabError, match=message):
        stability_map(pinstab.load_scene("fourbar"), **options)


def test_stability_map_raises_what_is_not_a_divergence():
    """A scene the runs cannot simulate is an error, not a map of "diverged" cells; a scene with velocity
    constraints only has no position error to repair."""
    import pinstab
    from pinstab.analysis.stability_map import stability_map
    from pinstab.errors import ServoInfeasibleError

    with pytest.raises(ServoInfeasibleError, match="cannot be realized at t = 0 s"):
        stability_map(pinstab.load_scene("ring-on-rod"), grid=2, steps=2)
    with pytest.raises(pinstab.PinstabError, match="violates no position constraint"):
        stability_map(pinstab.load_scene("rolling-disk"), grid=2, steps=2)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_decoupled_rows_give_the_eigenvalue_solves_radius(scheme):
    """With diagonal S and K the radius taken row by row equals the whole R(tau W)'s (holonomic and first-order
    rows mixed, two gain pairs); a coupled K goes to the eigenvalue solve of the whole R.

    Both gain pairs are critically damped (Kd^2 = 4 Kp): tau W has the double eigenvalues -1/10 and -1/5 (and -1/10
    on the first-order rows), so a Runge-Kutta scheme's rho is p(-1/10) exactly (rational arithmetic), 1e-12 rel.
    There R is defective (a Jordan block per holonomic row): the eigenvalue solve of the rounded R, backward error
    n eps |R| (n = 8), moves that double eigenvalue by up to sqrt(n eps |R| |N|), N = R_b - p(-1/10) I the block's
    nilpotent part (7.5e-8 here). Found: 3.6e-9 for DOPRI5, and for DOP853 with OpenBLAS's Haswell kernels (1e-16
    with its SkylakeX or Prescott ones), numpy 2.2 and 2.4 alike: the rounding of R's products splits the double
    eigenvalue into a real pair (rho moves by sqrt(delta)) or a complex one (by delta). Semi-implicit Euler's and
    held's R are not defective at these gains: their eigenvalue solve is the reference, 1e-12 rel."""
    mask = np.array([True, True, False, True, False])
    stiffness = np.eye(5)[:, mask] * np.array([100.0, 100.0, 400.0])
    damping = np.diag([20.0, 20.0, 10.0, 40.0, 10.0])
    whole = amplification(stiffness, damping, mask, 1e-2, scheme)
    solved = spectral_radius(whole)
    if scheme not in SPECIAL_SCHEMES:
        roots = (Fraction(-1, 10), Fraction(-1, 5))
        polynomial = regions.TABLEAUS[scheme].polynomial
        expected = max(abs(float(sum(Fraction(c) * mu**k for k, c in enumerate(polynomial)))) for mu in roots)
        block = amplification(np.array([[100.0]]), np.array([[20.0]]), np.array([True]), 1e-2, scheme)
        nilpotent = np.linalg.norm(block - expected * np.eye(2), 2)
        bound = math.sqrt(len(whole) * np.finfo(float).eps * np.linalg.norm(whole, 2) * nilpotent)
        assert solved == pytest.approx(expected, abs=bound)
    else:
        expected = solved
    assert deviation_radius(stiffness, damping, mask, 1e-2, scheme) == pytest.approx(expected, rel=1e-12)
    coupled = damping + 5.0 * np.eye(5, k=1)
    expected = spectral_radius(amplification(stiffness, coupled, mask, 1e-2, scheme))
    assert deviation_radius(stiffness, coupled, mask, 1e-2, scheme) == expected


# RK4's real boundary: the real root of 1 + x/2 + x^2/6 + x^3/24 (p(x) - 1 = x (...) / 24 on the real axis), negated
RK4_REAL_BOUND = -min(r.real for r in np.roots([1 / 24, 1 / 6, 1 / 2, 1]) if abs(r.imag) < 1e-12)


def _first_exit(polynomial: list[float], direction: complex) -> float:
    """The smallest x > 0 with |p(x u)| = 1 where |p| leaves the unit disk, for a polynomial p (lowest degree first)
    along the unit direction u: the smallest positive real root of (|p(x u)|^2 - 1) / x, from NumPy's roots of that
    real polynomial in x (the closed form the scan and bisection of mode_step_limit must meet)."""
    scaled = np.array([c * direction**k for k, c in enumerate(polynomial)])  # p(x u) in x, lowest first
    square = np.convolve(scaled, scaled.conj()).real  # |p(x u)|^2 in x
    square[0] -= 1.0
    roots = np.roots(square[1:][::-1])  # divided by x: the root x = 0 removed
    real = [r.real for r in roots if abs(r.imag) <= 1e-9 * abs(r) and r.real > 0]
    return min(real)


@pytest.mark.parametrize("modulus", [1e-3, 1.0, 7159.2, 1e9])
def test_mode_step_limit_meets_the_closed_forms(modulus):
    """The stability limit of a stiff mode of eigenvalue lambda: explicit Euler 2 / |lambda| on a real one and
    -2a / |lambda|^2 on a pair a +- ib; RK4 2.785293563 / |lambda| on a real one; on pairs, RK4's, Heun's and DOPRI5's
    first exit along the ray of lambda from the roots of |p(x u)|^2 = 1 (NumPy); semi-implicit Euler on a pair its
    2 x 2 step matrix's Jury conditions (det 1 - h kd >= -1 and trace 2 - h^2 kp - h kd >= -(1 + det), kp = |lambda|^2,
    kd = -2a), on a real one the first-order row 1 + h lambda; implicit Euler, the midpoint rule and ESDIRK4 (A-stable)
    none. To 1e-9 relative, at moduli from 1e-3 to 1e9 /s (the limit scales as 1 / |lambda|)."""
    assert RK4_REAL_BOUND == pytest.approx(2.785293563, abs=1e-9)
    real = -modulus
    assert mode_step_limit(real, "euler") == pytest.approx(2.0 / modulus, rel=1e-9)
    assert mode_step_limit(real, "semi-implicit-euler") == pytest.approx(2.0 / modulus, rel=1e-9)
    assert mode_step_limit(real, "rk4") == pytest.approx(RK4_REAL_BOUND / modulus, rel=1e-9)
    for angle in (0.3, 1.0, 1.55):  # from the negative real axis towards the imaginary one [rad]
        pair = modulus * complex(-math.cos(angle), math.sin(angle))
        a = pair.real
        assert mode_step_limit(pair, "euler") == pytest.approx(-2 * a / modulus**2, rel=1e-9)
        for scheme, polynomial in (
            ("heun", [1, 1, 1 / 2]),
            ("rk4", [1, 1, 1 / 2, 1 / 6, 1 / 24]),
            ("dopri5", [1, 1, 1 / 2, 1 / 6, 1 / 24, 1 / 120, 1 / 600]),
        ):
            expected = _first_exit(polynomial, pair / modulus) / modulus
            assert mode_step_limit(pair, scheme) == pytest.approx(expected, rel=1e-9), (scheme, angle)
        kp, kd = modulus**2, -2 * a
        jury = min(2 / kd, (-kd + math.sqrt(kd**2 + 4 * kp)) / kp)
        assert mode_step_limit(pair, "semi-implicit-euler") == pytest.approx(jury, rel=1e-9)
        for scheme in ("implicit-euler", "implicit-midpoint", "esdirk4"):
            assert mode_step_limit(pair, scheme) == math.inf
            assert mode_step_limit(real, scheme) == math.inf


def test_mode_step_limit_is_where_the_mode_starts_to_grow():
    """Just below the limit one step keeps the mode (|R| <= 1), just above it the mode grows (RK4 and DOP853 on a
    real and a lightly damped mode); a mode that grows on its own (Re lambda > 0) has limit 0 with an explicit scheme;
    an unknown scheme is refused, naming the valid ones."""
    for eigenvalue in (complex(-7159.2), complex(-1.3, 141.0)):
        for scheme in ("rk4", "dop853"):
            limit = mode_step_limit(eigenvalue, scheme)
            below, above = (mode_growth(eigenvalue, factor * limit, scheme) for factor in (0.999, 1.001))
            assert below <= 1.0 < above
    assert mode_step_limit(complex(5.0, 1.0), "rk4") == 0.0
    with pytest.raises(PinstabError, match=r"unknown integrator 'rk5'; valid integrators: .*esdirk4.*semi-implicit"):
        mode_step_limit(-1.0, "rk5")
