"""The discrete criterion: amplification matrices against the schemes written out by hand, gain
placement, stable-step bounds, and the criterion's predictions against real runs."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

from pinstab.stability.criterion import (
    POLYNOMIALS,
    SCHEMES,
    amplification,
    deviation_radius,
    largest_stable_step,
    place_gains,
    scalar_radius,
    spectral_radius,
)


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
    if scheme in POLYNOMIALS:
        roots = (Fraction(-1, 10), Fraction(-1, 5))
        expected = max(abs(float(sum(Fraction(c) * mu**k for k, c in enumerate(POLYNOMIALS[scheme])))) for mu in roots)
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
