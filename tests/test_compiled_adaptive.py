"""The compiled error-controlled loop (``cpp/adaptive.cpp``, :class:`~pinstab.integration.compiled.CompiledAdaptive`)
against the Python adaptive loop it takes the steps of: the same steps, samples and counts to the last bit on the
native and the banded paths for both embedded pairs; the compiled trial step, error norm, control and dense output
against independent NumPy forms of the same formulas (the tableau's sums, Hairer's combination, the PI control,
the quintic Hermite polynomial); the runs it leaves to Python."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import with_python_force
from pinstab import build_system, load_scene, simulate
from pinstab.analysis import exact_reference
from pinstab.integration import adaptive
from pinstab.integration.compiled import CompiledAdaptive, CompiledSteps, compiled_obstacle
from pinstab.integration.dense import HERMITE, QUINTIC, Segment
from pinstab.integration.schemes import INTEGRATORS
from pinstab.kernels import AdaptivePair, RungeKutta, hermite_coefficients, hermite_state


def _run_both(monkeypatch, scene, integrator, rtol, duration, **options):
    fast = simulate(scene, "baumgarte", integrator, 1e-2, duration, rtol=rtol, **options)
    with monkeypatch.context() as patch:
        patch.setattr(CompiledAdaptive, "of", classmethod(lambda cls, system, stepper, pair: None))
        slow = simulate(scene, "baumgarte", integrator, 1e-2, duration, rtol=rtol, **options)
    return fast, slow


def _assert_same_run(fast, slow) -> None:
    np.testing.assert_array_equal(fast.t, slow.t)
    np.testing.assert_array_equal(fast.q, slow.q)
    np.testing.assert_array_equal(fast.v, slow.v)
    assert fast.info.error_control == slow.info.error_control
    assert fast.info.solver_statistics.solves == slow.info.solver_statistics.solves


def test_native_kernel_with_force_elements_bitwise_equal_to_the_python_adaptive_loop(monkeypatch):
    """The slider-crank's torque and damper in the native kernel: dop853 at rtol 1e-7 over 1 s steps compiled, t, q,
    v, the accepted and rejected steps and the solves equal to the Python loop's (Python's elements) to the last
    bit."""
    fast, slow = _run_both(monkeypatch, load_scene("slider-crank"), "dop853", 1e-7, 1.0)
    assert fast.info.path == slow.info.path == "native"
    accepted = fast.info.error_control["steps_accepted"]
    assert accepted > 20 and fast.info.compiled_steps >= 0.8 * accepted and slow.info.compiled_steps == 0
    _assert_same_run(fast, slow)


@pytest.mark.parametrize(("integrator", "rtol"), [("dop853", 1e-8), ("dopri5", 1e-7)])
def test_fourbar_bitwise_equal_to_the_python_adaptive_loop(monkeypatch, integrator, rtol):
    """The four-bar over 10 s (the acceptance run of ``benchmarks/compiled_adaptive.py``): t, q, v, the accepted
    and rejected steps and the solves equal to the last bit; almost every step compiled (the first chunk's solves
    are checked in Python)."""
    fast, slow = _run_both(monkeypatch, load_scene("fourbar"), integrator, rtol, 10.0)
    assert fast.info.path == slow.info.path == "native"
    accepted = fast.info.error_control["steps_accepted"]
    assert accepted > 500 and fast.info.compiled_steps >= 0.9 * accepted and slow.info.compiled_steps == 0
    _assert_same_run(fast, slow)


def test_banded_path_bitwise_equal_through_a_singular_passage(monkeypatch):
    """The N-four-bar, N = 10 (banded), dop853 at rtol 3e-8 over 5 s, one sample in 3 kept: its passages through
    the aligned configuration are Python's steps (the watch plans them), the rest compiled; equal to the last bit."""
    fast, slow = _run_both(monkeypatch, load_scene("nfourbar", N=10), "dop853", 3e-8, 5.0, record_every=3)
    assert fast.info.path == "banded" and 0 < fast.info.compiled_steps < fast.info.error_control["steps_accepted"]
    _assert_same_run(fast, slow)


def test_the_compiled_run_matches_the_exact_motion():
    """Independent check: the compiled dop853 run of the four-bar at rtol 1e-8 over 2 s against the crank-angle
    equation's motion from the same start (:func:`~pinstab.analysis.exact_reference`): within 1e-6 rad."""
    scene = load_scene("fourbar")
    run = simulate(scene, "baumgarte", "dop853", 1e-2, 2.0, rtol=1e-8)
    exact = exact_reference(scene, run.q[0], run.v[0], run.t)
    assert run.info.compiled_steps > 0
    assert np.abs(run.q - exact.q).max() <= 1e-6


def _pair(integrator: str, rtol: float = 1e-6, atol: float = 1e-9) -> tuple[type, AdaptivePair]:
    stepper = INTEGRATORS.entry(integrator).factory
    constants = {
        "rtol": rtol,
        "atol": atol,
        "safety": adaptive.SAFETY,
        "min_factor": adaptive.MIN_FACTOR,
        "max_factor": adaptive.MAX_FACTOR,
        "min_step": adaptive.MIN_STEP,
        "pi_alpha": adaptive.PI_ALPHA,
        "pi_beta": adaptive.PI_BETA,
        "estimator_mix": adaptive.ESTIMATOR_MIX,
        "exponent": -1.0 / (stepper.tableau.estimator_order + 1),
    }
    return stepper, AdaptivePair(
        stepper.nodes, stepper.coupling, stepper.weights, stepper.estimators, HERMITE, constants
    )


@pytest.mark.parametrize("integrator", ["dop853", "dopri5"])
def test_trial_and_error_norm_match_the_tableau_in_numpy(integrator):
    """A step of the pendulum-like field a = -sin(q) - 0.1 v (2 coordinates): the compiled trial's stages, end state
    and error against the tableau applied with NumPy (stage sums, the estimators, max-norm scaling, Hairer's
    combination for DOP853), to 1e-14 relative."""
    stepper, pair = _pair(integrator)
    rng = np.random.default_rng(3)
    q, v, t, h = rng.normal(size=2), rng.normal(size=2), 0.3, 0.05

    def field(q_, v_, t_, stage):
        return -np.sin(q_) - 0.1 * v_ + 0.01 * t_

    trial = RungeKutta(stepper.nodes, stepper.coupling, stepper.weights, None)
    q_new, v_new, slopes, end = trial.attempt(
        field, q, v, t, h, field(q, v, t, 0), bool(stepper.estimators[:, -1].any())
    )
    expected = np.zeros((stepper.stages, 4))
    for i in range(stepper.stages):
        state = np.concatenate((q, v)) + h * stepper.coupling[i, :i] @ expected[:i]
        expected[i] = np.concatenate((state[2:], field(state[:2], state[2:], t + stepper.nodes[i] * h, i)))
    np.testing.assert_allclose(slopes, expected, rtol=1e-14, atol=1e-15)
    increment = h * stepper.weights @ expected
    np.testing.assert_allclose(q_new, q + increment[:2], rtol=1e-14)
    np.testing.assert_allclose(v_new, v + increment[2:], rtol=1e-14)
    estimates = stepper.estimators[:, : stepper.stages] @ expected
    if end is not None:
        np.testing.assert_allclose(end, np.concatenate((v_new, field(q_new, v_new, t + h, 0))), rtol=1e-15)
        estimates += np.outer(stepper.estimators[:, -1], end)
    size, size_new = np.abs(np.concatenate((q, v))), np.abs(np.concatenate((q_new, v_new)))
    largest = np.abs(estimates / (1e-9 + 1e-6 * np.maximum(size, size_new))).max(axis=1)
    if len(largest) == 1:
        error = h * largest[0]
    else:
        error = h * largest[0] ** 2 / math.sqrt(largest[0] ** 2 + adaptive.ESTIMATOR_MIX * largest[1] ** 2)
    assert pair.error(size, size_new, slopes, end, h) == pytest.approx(error, rel=1e-12)


def test_step_control_matches_its_formula():
    """The PI control after an accepted step (0.9 err^(-0.7/8) prev^(0.4/8), between 0.2 h and 10 h, no growth right
    after a rejection, the proposed step when h was shortened) and the shrink after a rejection, to 1e-15."""
    _, pair = _pair("dop853")
    h, error, previous = 0.01, 0.3, 0.5
    optimal = h * 0.9 * error ** (-0.7 / 8) * previous ** (0.4 / 8)
    assert pair.next_step(h, error, h, previous, False) == pytest.approx(optimal, rel=1e-15)
    assert pair.next_step(h, 1e-30, h, previous, False) == pytest.approx(10 * h, rel=1e-15)
    assert pair.next_step(h, 1e-30, h, previous, True) == pytest.approx(h, rel=1e-15)
    assert pair.next_step(h / 2, 1e-30, h, previous, False) == pytest.approx(10 * h, rel=1e-15)  # shortened step
    assert pair.next_step(h, 0.0, h, previous, False) == pytest.approx(10 * h, rel=1e-15)
    assert pair.shrink(h, 4.0) == pytest.approx(h * 0.9 * 4.0 ** (-1 / 8), rel=1e-15)
    assert pair.shrink(h, 1e30) == pytest.approx(0.2 * h, rel=1e-15)
    assert pair.shrink(h, math.nan) == pytest.approx(0.2 * h, rel=1e-15)


def test_hermite_output_is_the_quintic_through_the_ends():
    """The dense output's polynomial of p(u) = 1 + 2u - u^2 + 0.5u^3 + 3u^4 - u^5 from its ends (p, p', p'' at 0 and
    1) returns p(u) and p'(u) / h to 1e-14."""
    c = np.array([1.0, 2.0, -1.0, 0.5, 3.0, -1.0])
    p = np.polynomial.Polynomial(c)
    ends = np.array([[p(0.0)], [p.deriv()(0.0)], [p.deriv(2)(0.0)], [p(1.0)], [p.deriv()(1.0)], [p.deriv(2)(1.0)]])
    coefficients = hermite_coefficients(QUINTIC, ends)
    np.testing.assert_allclose(coefficients[:, 0], c, rtol=1e-13, atol=1e-13)
    increment, rate = hermite_state(coefficients, 0.37, 0.02)
    assert increment[0] == pytest.approx(p(0.37), rel=1e-14)
    assert rate[0] == pytest.approx(p.deriv()(0.37) / 0.02, rel=1e-14)


def test_bad_shapes_are_refused():
    """An error norm given slopes of another pair, Hermite values of another degree, a trial step from a state of mixed
    sizes or with accelerations of another size raise."""
    stepper, pair = _pair("dop853")
    with pytest.raises(ValueError):
        pair.error(np.ones(4), np.ones(4), np.zeros((7, 4)), None, 0.1)
    with pytest.raises(ValueError):
        hermite_coefficients(QUINTIC, np.zeros((4, 2)))
    trial = RungeKutta(stepper.nodes, stepper.coupling, stepper.weights, None)
    with pytest.raises(ValueError):
        trial.attempt(lambda q, v, t, stage: np.zeros(3), np.zeros(2), np.zeros(2), 0.0, 0.1)
    with pytest.raises(ValueError):
        trial.attempt(lambda q, v, t, stage: np.zeros(2), np.zeros(3), np.zeros(2), 0.0, 0.1)


def _loaded(scene: str):
    """The bundled scene; "slider-crank+user": with a user's force element (conftest.with_python_force)."""
    return with_python_force(load_scene("slider-crank")) if scene == "slider-crank+user" else load_scene(scene)


@pytest.mark.parametrize(
    ("scene", "method", "solver"),
    [("slider-crank+user", "baumgarte", None), ("fourbar", "projection", None), ("fourbar", "baumgarte", "dense")],
)
def test_runs_of_the_python_evaluation_match_the_python_loop(monkeypatch, scene, method, solver):
    """A force element without a compiled form (a user's, added to the slider-crank) and the general path run the
    compiled loop on the system's Python evaluation (called back), a correcting method (projection) keeps the Python
    loop: no step of a compiled kernel, the same run as with the compiled loop switched off, to the last bit."""
    made: list[CompiledAdaptive] = []
    original = CompiledAdaptive.__init__

    def spy(self, system, pair):
        original(self, system, pair)
        made.append(self)

    with monkeypatch.context() as patch:
        patch.setattr(CompiledAdaptive, "__init__", spy)
        fast = simulate(_loaded(scene), method, "dop853", 1e-2, 0.5, rtol=1e-7, solver=solver)
    with monkeypatch.context() as patch:
        patch.setattr(CompiledAdaptive, "of", classmethod(lambda cls, system, stepper, pair: None))
        slow = simulate(_loaded(scene), method, "dop853", 1e-2, 0.5, rtol=1e-7, solver=solver)
    accepted = fast.info.error_control["steps_accepted"]
    assert fast.info.compiled_steps == 0 and accepted > 0
    if method == "projection":
        assert not made
    else:
        assert len(made) == 1 and made[0].callback_steps >= 0.9 * accepted
    _assert_same_run(fast, slow)


def test_free_flyer_compiled_loop_equals_the_python_loop(monkeypatch):
    """The full cassie (floating base, 16 closures, the core path), dop853 at rtol 1e-8 over 0.05 s: the compiled loop
    on the configuration group (increments in the tangent space, the dense output's velocities carried back through
    dDifference) takes the Python loop's steps and samples to the last bit, and the samples stay on the mechanism
    (closure residual below 1e-7 m)."""
    scene = load_scene("cassie")
    fast, slow = _run_both(monkeypatch, scene, "dop853", 1e-8, 0.05)
    assert fast.info.path == "core" and fast.info.compiled_steps >= 0.9 * fast.info.error_control["steps_accepted"]
    _assert_same_run(fast, slow)
    system = build_system(scene, "baumgarte")
    assert max(system.model.violation(q, v, 0.0)[0] for q, v in zip(fast.q, fast.v, strict=True)) <= 1e-7


def test_dense_output_on_the_group_meets_the_step_ends():
    """dop853 steps of the full cassie (free flyer) from its start, every coordinate moving: the dense output returns
    the step's start exactly and its end to 1e-12 (q through q0 (+) (q0 (-) q1), v through dDifference and back), and
    at the step's middle agrees with a step of half the length from the same start, the gap shrinking as h^5 (the
    quartic on the group: by 16 at least when h halves; below 1e-10 rad or m at h = 0.5 ms)."""
    scene = load_scene("cassie")
    system = build_system(scene, "baumgarte")
    system.bind(1e-2, "dop853", scene.q0)
    stepper, model = INTEGRATORS.build("dop853", system), system.model
    q0, v0 = scene.q0, scene.v0 + 0.3 * np.sin(np.arange(len(scene.v0)))  # the base's rotation included
    a0 = system.acceleration(q0, v0, 0.0, 0)
    gaps = []
    for h in (1e-3, 5e-4):
        q1, v1 = stepper.attempt(q0, v0, 0.0, h, a0)[:2]
        segment = Segment(model, 0.0, q0, v0, a0, h, q1, v1, system.acceleration(q1, v1, h, 0))
        q, v = segment.state(0.0)
        np.testing.assert_array_equal(q, q0)
        np.testing.assert_allclose(v, v0, rtol=0, atol=1e-14)
        q, v = segment.state(h)
        np.testing.assert_allclose(model.difference(q1, q), 0.0, atol=1e-12)
        np.testing.assert_allclose(v, v1, rtol=0, atol=1e-12 * max(1.0, np.abs(v1).max()))
        q_half = stepper.attempt(q0, v0, 0.0, h / 2, a0)[0]
        gaps.append(np.abs(model.difference(q_half, segment.state(h / 2)[0])).max())
    assert gaps[0] / gaps[1] >= 16 and gaps[1] <= 1e-10


def test_general_path_fixed_steps_run_compiled_on_the_python_evaluation(monkeypatch):
    """The four-bar on the general path (proxsuite), RK4: the compiled fixed-step loop calls the system's evaluation
    back and takes the Python loop's steps to the last bit (the solves counted alike)."""
    scene = load_scene("fourbar")
    fast = simulate(scene, "baumgarte", "rk4", 1e-3, 0.3, solver="proxsuite")
    with monkeypatch.context() as patch:
        patch.setattr(CompiledSteps, "of", classmethod(lambda cls, system, stepper: None))
        slow = simulate(scene, "baumgarte", "rk4", 1e-3, 0.3, solver="proxsuite")
    assert fast.info.path == "general"
    _assert_same_run(fast, slow)


def test_an_exception_of_the_python_evaluation_reaches_the_caller():
    """An evaluation that raises inside a compiled run (here after 5 calls) ends the run: the steps before it are
    handed back and the exception itself is raised, unchanged, by the caller."""
    scene = load_scene("fourbar")
    system = build_system(scene, "baumgarte")
    system.bind(1e-2, "rk4", scene.q0)
    steps = CompiledSteps(system, INTEGRATORS.build("rk4", system))
    steps.compiled = False
    calls = []

    def failing(q, v, t, stage):
        calls.append(t)
        if len(calls) > 5:
            raise KeyError("the fifth")
        return np.zeros_like(v)

    system.acceleration = failing
    qs, vs, done, raised, iterations = steps.run(scene.q0, scene.v0, 0, 1e-2, 10)
    assert (
        iterations is None
        and done == 1
        and len(qs) == 1
        and isinstance(raised, KeyError)
        and raised.args == ("the fifth",)
    )
    np.testing.assert_allclose(qs[0], scene.q0 + 1e-2 * scene.v0, rtol=1e-15)


def test_compiled_obstacle_of_an_embedded_pair():
    """An error-controlled dop853 run of the four-bar on the native path has no obstacle (nor its fixed steps), one
    with the projection method has its reason."""
    scene = load_scene("fourbar")
    system = build_system(scene, "baumgarte")
    system.bind(1e-2, "dop853", scene.q0)
    stepper = INTEGRATORS.build("dop853", system)
    assert compiled_obstacle(system, stepper) is None
    assert compiled_obstacle(system, stepper, adaptive=True) is None
    system = build_system(scene, "projection")
    system.bind(1e-2, "dop853", scene.q0)
    assert "corrects" in compiled_obstacle(system, INTEGRATORS.build("dop853", system), adaptive=True)
