"""Singular passages of the N-four-bar: every method keeps the exact motion through them, every passage is
listed, and a change of branch is told apart from a kept branch by the exact motion itself."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pinstab import BranchChangeWarning, load_scene, simulate, trajectory_error
from pinstab.integration.passages import LOCATE_TOLERANCE, PassageWatch, _least, _parabola_roots, node_gap, tangent_turn

DURATION = 5.0  # [s] five passages (from the upright start at -1 rad/s)


def exact_passages(n: int, duration: float) -> np.ndarray:
    """Times [s] where the exact crank angle crosses pi/2 + k pi (all links aligned), from the pendulum."""
    inertia, stiffness = (n + 1) / 3 + n, 9.81 * ((n + 1) / 2 + n)
    t = np.linspace(0.0, duration, 200_001)
    theta = solve_ivp(
        lambda _, y: [y[1], stiffness / inertia * np.sin(y[0])],
        (0.0, duration),
        [0.0, -1.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=t,
    ).y[0]
    branch = np.floor((theta - np.pi / 2) / np.pi)
    return t[1:][np.diff(branch) != 0]


@pytest.mark.parametrize("n", [1, 2, 5, 10, 20])
@pytest.mark.parametrize("method", ["baumgarte", "projection", "post", "mukharlyamov"])
def test_every_method_keeps_the_exact_motion_through_the_passages(n, method):
    """RK4 at 1 ms over 5 s: crank error <= 1e-8 rad against the exact pendulum (the issue's bound is 1e-6;
    measured 2e-11 ... 1.7e-9 over 20 s, benchmarks/results/singular_passages.json), every exact passage
    listed within 2 ms with s < 1e-3 and the branch kept."""
    scene = load_scene("nfourbar", N=n)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BranchChangeWarning)
        run = simulate(scene, method=method, integrator="rk4", dt=1e-3, duration=DURATION)
    assert trajectory_error(run, "exact", scene=scene).error.max() <= 1e-8
    passages = run.info.passages
    expected = exact_passages(n, DURATION)
    assert len(passages) == len(expected) == 5
    np.testing.assert_allclose([p["t"] for p in passages], expected, atol=2e-3)
    assert all(p["branch_kept"] and p["min_relative_singular_value"] < 1e-3 for p in passages)
    assert all(p["rank"] < p["generic_rank"] == 2 * n for p in passages)
    assert run.summary()["branch_changes"] == 0


def test_a_branch_change_is_reported_where_the_exact_motion_is_lost():
    """Without stabilization (``none``, N = 10, RK4 1 ms) the motion leaves the parallelogram branch at the
    fourth passage (t = 3.2 s): the warning and the passage say so, and the exact reference agrees: the
    crank error is below 1e-5 rad before it (measured 2.2e-6 on the default banded path, 1.8e-7 on Pinocchio's
    solve: unstabilized, the motion amplifies rounding at each passage, by turns more on either path; at N = 6,
    8, 12, 16, 30 over 2.5 s the two are within 10x of each other, either way) and above 1e-2 rad 0.4 s after it."""
    scene = load_scene("nfourbar", N=10)
    with pytest.warns(BranchChangeWarning, match="left its branch at a singular configuration"):
        run = simulate(scene, method="none", integrator="rk4", dt=1e-3, duration=3.6)
    kept = [p["branch_kept"] for p in run.info.passages]
    assert kept == [True, True, True, False]
    change = run.info.passages[-1]["t"]
    error = trajectory_error(run, "exact", scene=scene).error[:, 0]
    assert error[run.t < change - 0.01].max() < 1e-5 and error[-1] > 1e-2


def test_large_steps_list_every_passage():
    """At dt = 20 ms (RK4, baumgarte) the watch samples s often enough not to step over a dip: all five
    passages of the first 5 s are listed (a doubling schedule alone skipped the second and fourth)."""
    run = simulate(load_scene("nfourbar", N=5), method="baumgarte", integrator="rk4", dt=2e-2, duration=DURATION)
    np.testing.assert_allclose([p["t"] for p in run.info.passages], exact_passages(5, DURATION), atol=2e-2)


def test_tangent_turn_is_the_largest_principal_angle():
    """Two planes in R^3 at a dihedral angle a: principal angles (0, a); the turn is a to 1e-12."""
    for angle in (1e-9, 1e-3, 0.7):
        before = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
        after = np.array([[1.0, 0.0], [0.0, np.cos(angle)], [0.0, np.sin(angle)]])
        assert abs(tangent_turn(before, after) - angle) < 1e-12 * max(1.0, angle)


def test_rk4_stage_gap_and_crossing_prediction():
    """RK4's stages at 0, 1/2, 1: widest gap centred at 3/4 (half-width 1/4). A watch fed s = |t - 0.3|
    samples predicts the crossing at 0.3 s from two falling samples."""
    assert node_gap([0.0, 0.5, 0.5, 1.0]) == (0.75, 0.25)  # of the two equal gaps, the later
    watch = PassageWatch.__new__(PassageWatch)
    watch.samples = [(0.1, 0.2, None), (0.2, 0.1, None)]
    assert abs(watch.crossing() - 0.3) < 1e-12
    watch.samples = [(0.0, 0.3 - 0.0**2, None), (0.1, 0.3 - 0.1**2 * 10, None), (0.15, 0.3 - 0.15**2 * 10, None)]
    assert abs(watch.crossing() - np.sqrt(0.03)) < 1e-9  # the parabola's root, before the line's


def test_parabola_roots_through_three_samples():
    """The crossing's parabola: through (0.1, s(0.1)), (0.3, s(0.3)), (0.6, s(0.6)) of s = 2 (t - 0.45)(t - 0.9), its
    roots 0.45 and 0.9 (as times after 0.3: 0.15, 0.6) to 1e-14; a line (a = 0) has one; no real root, none."""
    samples = [(t, 2 * (t - 0.45) * (t - 0.9), None) for t in (0.1, 0.3, 0.6)]
    np.testing.assert_allclose(sorted(_parabola_roots(samples, 0.3)), [0.15, 0.6], rtol=0, atol=1e-14)
    assert _parabola_roots([(t, 1.0 - t, None) for t in (0.0, 0.5, 1.0)], 0.0) == pytest.approx([1.0], abs=1e-15)
    assert _parabola_roots([(t, 1.0 + t * t, None) for t in (-1.0, 0.0, 1.0)], 0.0) == []


@pytest.mark.parametrize(
    ("crossing", "floor", "expected"),
    [
        (0.0264, 0.0, 0.0264),  # a crossing through the singular configuration, early in the step
        (0.7897, 1e-9, 0.7897),  # one that misses it by a little
        (0.31, 1e-4, 0.31),
        (1.3, 0.0, 1.0),  # s falls all through the step: the least at its end
        (-0.2, 0.0, 0.0),  # s rises all through the step: the least at its start
    ],
)
def test_the_least_relative_singular_value_is_located_in_few_evaluations(crossing, floor, expected):
    """s = sqrt(a^2 (t - t*)^2 + c^2) (with a curve in the slope, as across a real step) on a step of h = 0.06 s:
    the least s and its time against the closed form, to the location tolerance, in at most 14 evaluations
    (Brent's search on the V of s falls back to golden sections: ~log(1e9)/log(1.618) of them)."""
    h, t0 = 0.06, 4.0
    evaluations = []

    def level(t: float) -> float:
        evaluations.append(t)
        x = (t - t0) / h - crossing
        return float(np.sqrt((0.8 * x * (1 + 0.4 * x)) ** 2 + floor**2))

    least, time = _least(level, t0, t0 + h, h)
    assert time == pytest.approx(t0 + expected * h, abs=10 * LOCATE_TOLERANCE * h)
    assert least == pytest.approx(level(time), rel=1e-12)
    assert least <= min(level(t0 + k * h / 1000) for k in range(1001)) * (1 + 1e-9) + 1e-15
    assert len(evaluations) - 1002 <= 14
