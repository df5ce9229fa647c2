"""Stability functions of Runge-Kutta tableaus (pinstab.stability.regions), the growth per step they give a linear
motion (pinstab.stability.criterion.step_growth), and the stability maps of a stiff force element
(pinstab.analysis.element_map, ``pinstab stability --element``), issue 37."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pinstab
from pinstab.analysis.element_map import ElementMap, element_map, plot_element_map, scaled_scene
from pinstab.cli import main
from pinstab.errors import PinstabError
from pinstab.model import ConstrainedModel
from pinstab.stability import regions
from pinstab.stability.criterion import largest_stable_step, mode_step_limit, step_growth
from pinstab.stability.modes import linearize, stiffest_mode

# the real root of z^3 + 4 z^2 + 12 z + 24 = 0: where RK4's polynomial is 1 on the negative real axis (p(z) - 1 = z/24
# (z^3 + 4 z^2 + 12 z + 24)), its region's real boundary
RK4_REAL_BOUNDARY = float(min(np.roots([1.0, 4.0, 12.0, 24.0]), key=lambda root: abs(root.imag)).real)


@pytest.fixture
def implicit_schemes():
    """Implicit Euler and the implicit midpoint rule, registered by their one-stage tableaus for the test (the
    integrators' own, behind an explicit first stage, restored after it)."""
    registered = {name: regions.TABLEAUS[name] for name in ("implicit-euler", "implicit-midpoint")}
    regions.register_tableau("implicit-euler", [[1.0]], [1.0])
    regions.register_tableau("implicit-midpoint", [[0.5]], [1.0])
    yield ("implicit-euler", "implicit-midpoint")
    regions.TABLEAUS.update(registered)


def _left_half_plane() -> np.ndarray:
    """z = h lambda over the closed left half-plane: moduli 1e-6 .. 1e8, angles from the imaginary axis to the
    negative real axis."""
    radii = np.geomspace(1e-6, 1e8, 57)
    angles = np.linspace(np.pi / 2, np.pi, 31)
    return (radii[:, None] * np.exp(1j * angles[None, :])).ravel()


TAYLOR = {"euler": (1.0, 1.0), "heun": (1.0, 1.0, 0.5), "rk4": (1.0, 1.0, 1 / 2, 1 / 6, 1 / 24)}
"""The stability polynomials of the schemes of order s with s stages: the Taylor coefficients 1 / k! of e^z."""


def test_stability_function_of_an_explicit_tableau_is_its_polynomial():
    """R(z) = 1 + z b^T (I - z A)^-1 1 from the tableau equals its stability polynomial (coefficients 1/k!), to
    rounding, at points inside and far outside the region; the polynomial the registry derives from the tableau (for
    the deviation criterion) is those coefficients to the last bit (rational arithmetic: RK4's b^T 1 is 1)."""
    rng = np.random.default_rng(3)
    z = rng.normal(size=40) * 3 + 1j * rng.normal(size=40) * 3
    for scheme, coefficients in TAYLOR.items():
        polynomial = np.polyval(np.array(coefficients[::-1]), z)
        values = regions.stability_function(scheme, z)
        np.testing.assert_allclose(values, polynomial, rtol=1e-13, atol=1e-13)
        assert regions.TABLEAUS[scheme].explicit and regions.TABLEAUS[scheme].polynomial == coefficients


def test_implicit_euler_and_midpoint_stability_functions(implicit_schemes):
    """Implicit Euler: R = 1 / (1 - z); the midpoint rule: R = (1 + z/2) / (1 - z/2), |R| = 1 on the imaginary axis.
    To the rounding unit in absolute terms (1 + z b^T k cancels to |R| ~ 1 / |z| far out: what decides stability is
    |R| against 1)."""
    z = _left_half_plane()
    implicit_euler = np.abs(regions.stability_function("implicit-euler", z))
    np.testing.assert_allclose(implicit_euler, 1 / np.abs(1 - z), rtol=1e-13, atol=1e-15)
    midpoint = regions.stability_function("implicit-midpoint", z)
    np.testing.assert_allclose(midpoint, (1 + z / 2) / (1 - z / 2), rtol=1e-13, atol=1e-15)
    axis = 1j * np.geomspace(1e-3, 1e6, 50)
    np.testing.assert_allclose(np.abs(regions.stability_function("implicit-midpoint", axis)), 1.0, rtol=1e-12)
    assert not regions.TABLEAUS["implicit-euler"].explicit
    assert np.isinf(regions.stability_function("implicit-euler", 1.0 + 0j)).all()  # its pole


def test_a_stable_schemes_are_stable_on_the_whole_left_half_plane(implicit_schemes):
    """|R(z)| <= 1 on every sampled point of the left half-plane for implicit Euler and the midpoint rule; the
    explicit schemes leave their region there (RK4 at z = -3, beyond its real boundary -2.785)."""
    z = _left_half_plane()
    for scheme in implicit_schemes:
        assert np.abs(regions.stability_function(scheme, z)).max() <= 1.0 + 1e-12, scheme
    for scheme in ("euler", "heun", "rk4"):
        assert np.abs(regions.stability_function(scheme, z)).max() > 1.0, scheme
    assert abs(regions.stability_function("rk4", -3.0)[0]) > 1.0
    # on a stiff linear motion (a spring-damper of eigenvalues -1e-3 and -1e3 /s), no step leaves their region
    for scheme in implicit_schemes:
        for dt in np.geomspace(1e-6, 1e3, 10):
            assert step_growth(scheme, float(dt), np.array([[1.0]]), np.array([[1000.001]])).excess <= 1.0
        assert mode_step_limit(-1e3, scheme) == np.inf


def test_rk4_growth_on_a_linear_spring_damper_leaves_the_region_at_its_real_boundary_over_lambda():
    """x'' = -x - 1000.001 x' (eigenvalues -1e3 and -1e-3 /s): RK4's step leaves its region at 2.7853 / 1000 s, the
    real root of its boundary over |lambda|, Euler's at 2 / 1000 s (each its mode of -1e3 /s: mode_step_limit, 8
    digits), and the growth per step is then the stiff mode's |p(h lambda)|."""
    assert RK4_REAL_BOUNDARY == pytest.approx(-2.785293563, abs=1e-9)
    stiffness, damping = np.array([[1.0]]), np.array([[1000.001]])
    for scheme, boundary in (("rk4", -RK4_REAL_BOUNDARY), ("euler", 2.0)):
        limit = mode_step_limit(-1e3, scheme)
        assert limit == pytest.approx(boundary / 1000.0, rel=1e-8)
        assert step_growth(scheme, 0.999 * limit, stiffness, damping).excess <= 1.0
        assert step_growth(scheme, 1.001 * limit, stiffness, damping).excess > 1.0


@pytest.mark.parametrize("scheme", ["euler", "semi-implicit-euler", "heun", "rk4"])
@pytest.mark.parametrize(("kp", "kd"), [(1.6e5, 7.2e3), (1e4, 20.0), (1e6, 2e3)])
def test_step_growth_leaves_the_region_at_the_deviation_criterions_bound(scheme, kp, kd):
    """On x'' = -kp x - kd x' the growth per step from the tableau's R at the eigenvalues (or semi-implicit Euler's step
    matrix) crosses 1 at the deviation criterion's largest stable step (its polynomials and 2 x 2 closed forms, and its
    scan: pinstab.stability.criterion.largest_stable_step), for overdamped, lightly damped and critically damped
    modes: at most 1 at 1 - 1e-7 of it, above 1 at 1 + 1e-7."""
    stiffness, damping = np.array([[kp]]), np.array([[kd]])
    bound = largest_stable_step(stiffness, damping, np.array([True]), scheme)
    assert step_growth(scheme, bound * (1 - 1e-7), stiffness, damping).excess <= 1.0
    assert step_growth(scheme, bound * (1 + 1e-7), stiffness, damping).excess > 1.0


def test_register_tableau_refuses_shapes_that_do_not_match():
    with pytest.raises(PinstabError, match="tableau of 'bad'"):
        regions.register_tableau("bad", [[0.0, 0.0], [1.0, 0.0]], [1.0])
    with pytest.raises(PinstabError, match="tableau of 'bad'"):
        regions.register_tableau("bad", [[np.nan]], [1.0])
    with pytest.raises(PinstabError, match="no stability function for integrator 'nope'.*rk4"):
        regions.stability_function("nope", 0.0)
    assert "bad" not in regions.TABLEAUS


def test_scaled_scene_scales_the_element_through_its_force_table():
    """The factor reaches the element's law (stiffness, and damping unless scale="stiffness") and its linearized
    mode: scaled together by 10, the stiff eigenvalue (about -c / m, damping-dominated) moves by 10 within 1 %."""
    scene = pinstab.load_scene("stiff-fourbar")
    both = scaled_scene(scene, "rocker-spring", 10.0)
    alone = scaled_scene(scene, "rocker-spring", 10.0, scale="stiffness")
    assert (both.forces[0].stiffness, both.forces[0].damping) == (5e5, 2.5e4)
    assert (alone.forces[0].stiffness, alone.forces[0].damping) == (5e5, 2.5e3)
    assert (scene.forces[0].stiffness, scene.forces[0].damping) == (5e4, 2.5e3)
    base = stiffest_mode(ConstrainedModel(scene), scene.q0, scene.v0, 0.0).eigenvalue
    scaled = stiffest_mode(ConstrainedModel(both), both.q0, both.v0, 0.0).eigenvalue
    assert scaled / base == pytest.approx(10.0, rel=1e-2)
    with pytest.raises(PinstabError, match="no force element 'crank'.*rocker-spring"):
        scaled_scene(scene, "crank", 2.0)


def test_implicit_euler_is_predicted_stable_on_the_whole_stiff_map(implicit_schemes):
    """On stiff-fourbar's linearization at every scale of the map (1e-2 .. 1e2), no step up to 10 ms takes a mode of
    implicit Euler or the midpoint rule outside its region, where RK4's stiff limit falls below 1e-5 s."""
    scene = pinstab.load_scene("stiff-fourbar")
    for factor in (1e-2, 1.0, 1e2):
        scaled = scaled_scene(scene, "rocker-spring", factor)
        linear = linearize(ConstrainedModel(scaled), scaled.q0, scaled.v0, 0.0)
        stiffness = np.linalg.solve(linear.mass, linear.stiffness.sum(axis=0))
        damping = np.linalg.solve(linear.mass, linear.damping.sum(axis=0))
        for dt in np.geomspace(1e-5, 1e-2, 7):
            for scheme in implicit_schemes:
                assert step_growth(scheme, dt, stiffness, damping).excess <= 1.0
        stiff = stiffest_mode(ConstrainedModel(scaled), scaled.q0, scaled.v0, 0.0).eigenvalue
        assert (mode_step_limit(stiff, "rk4") < 1e-5) == (factor == 1e2)


@pytest.fixture(scope="module")
def small_map() -> ElementMap:
    """A 10 x 10 map of stiff-fourbar (100-step runs) for Euler, Heun and RK4."""
    return element_map(
        pinstab.load_scene("stiff-fourbar"), "rocker-spring", ["euler", "heun", "rk4"], grid=10, steps=100
    )


def test_element_map_agrees_with_the_prediction(small_map, tmp_path):
    """Predicted (no mode grows 1000x over the run) and observed (the run did not gain 1e6 x its start's energy)
    agree on >= 95 % of the cells of each explicit scheme; the smallest step at the softest scale is stable and the
    largest step at the stiffest scale diverges for all three."""
    for name in ("euler", "heun", "rk4"):
        assert small_map.agreement(name) >= 0.95, name
        own = [c for c in small_map.cells if c.integrator == name]
        corner = {(c.dt, c.factor): c for c in own}
        assert corner[(1e-5, 1e-2)].observed == "dissipative" and corner[(1e-5, 1e-2)].predicted_stable
        assert corner[(1e-2, 1e2)].observed == "diverged" and not corner[(1e-2, 1e2)].predicted_stable
    png = plot_element_map(small_map, tmp_path / "map.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_an_unsolved_stage_is_its_own_class_and_counts_against_a_stable_prediction():
    """esdirk4 at dt = 10 ms with the element 100 times stiffer: Newton finds no root of the first step's stage on
    the motion's branch. The run stops with the NewtonError as the cause of the stop the loop names (a smaller step
    goes on), and the map calls the cell ``unsolved``, not ``diverged``: the scheme is A-stable and predicted stable,
    so the cell disagrees."""
    scene = scaled_scene(pinstab.load_scene("stiff-fourbar"), "rocker-spring", 100.0)
    with pytest.raises(pinstab.DivergenceError) as caught:
        pinstab.simulate(scene, integrator="esdirk4", dt=1e-2, duration=0.05, limits=False)
    assert isinstance(caught.value.__cause__, pinstab.NewtonError)
    result = element_map(
        pinstab.load_scene("stiff-fourbar"),
        "rocker-spring",
        ["esdirk4"],
        dt_range=(5e-3, 1e-2),
        factor_range=(50.0, 100.0),
        grid=2,
        steps=5,
    )
    cell = {(c.dt, c.factor): c for c in result.cells}[(1e-2, 100.0)]
    assert cell.observed == "unsolved" and cell.predicted_stable
    unsolved = result.to_json(cells=False)["schemes"]["esdirk4"]["unsolved"]
    assert unsolved >= 1 and result.agreement("esdirk4") == pytest.approx(1 - unsolved / 4, abs=1e-12)


def test_element_map_names_the_stiff_mode_and_its_limits(small_map):
    """The criterion names the element and frequency of the stiffest mode at the base scale; each scheme's limit is
    ``mode_step_limit`` of the mode's eigenvalue (RK4: 0.389 ms, 2.7853 / 7159.2 /s)."""
    scene = pinstab.load_scene("stiff-fourbar")
    mode = stiffest_mode(ConstrainedModel(scene), scene.q0, scene.v0, 0.0)
    payload = small_map.to_json(cells=False)
    assert payload["stiffest_mode"]["element"] == "rocker-spring"
    assert payload["stiffest_mode"]["frequency"] == pytest.approx(mode.frequency, rel=1e-12)
    for name in ("euler", "heun", "rk4"):
        assert payload["schemes"][name]["limit_dt"] == mode_step_limit(mode.eigenvalue, name)
    assert payload["schemes"]["rk4"]["limit_dt"] == pytest.approx(3.89e-4, rel=2e-3)
    assert "force element 'rocker-spring' (375.3 rad/s, lambda = -7159 /s)" in payload["criterion"]
    assert "rk4 0.389 ms" in payload["criterion"]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"dt_range": (1e-2, 1e-3)}, "dt range must be two increasing"),
        ({"factor_range": (0.0, 1.0)}, "factor range must be two increasing"),
        ({"grid": 1}, "grid must be a whole number from 2"),
        ({"steps": 10**7}, "3 maps of 40 x 40 runs"),
        ({"integrators": ["held"]}, "among those with a known stability function"),
        ({"integrators": ["rk4", "rk4"]}, "each once"),
        ({"scale": "mass"}, "scale must be one of"),
    ],
)
def test_element_map_refuses_arguments_out_of_range(options, message):
    options = {"integrators": ["euler", "heun", "rk4"]} | options
    with pytest.raises(PinstabError, match=message):
        element_map(pinstab.load_scene("stiff-fourbar"), "rocker-spring", **options)


def test_cli_element_map(tmp_path, capsys):
    """``pinstab stability stiff-fourbar``: an element map by default (no constraints: no gains to sweep), one panel
    per ``--integrator``; a gains option is refused, naming it; on the four-bar the gains map stays."""
    png = tmp_path / "map.png"
    argv = ["stability", "stiff-fourbar", "--grid", "3", "--steps", "20", "--quiet", "--json", "-o", str(png)]
    assert main([*argv, "--integrator", "rk4", "--integrator", "euler"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["kind"] == "element" and payload["element"] == "rocker-spring"
    assert list(payload["schemes"]) == ["rk4", "euler"] and len(payload["cells"]) == 18
    assert png.is_file()
    assert main(["stability", "stiff-fourbar", "--grid", "3", "--quiet", "--gain-range", "1", "10"]) == 2
    assert "--gain-range: not an option of an element map" in capsys.readouterr().err
    assert main(["stability", "fourbar", "--grid", "2", "--steps", "5", "--quiet", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["kind"] == "gains"
