"""The diagonally implicit schemes (``cpp/implicit.cpp``, :mod:`pinstab.integration.implicit`): the ESDIRK's
coefficients by the order conditions; one step on a linear oscillator against each scheme's stability function of
h A (closed forms); the order of convergence on the pendulum-like four-bar; the stiff four-bar against its SciPy Radau
reference where RK4 diverges; the constrained four-bar against its exact reference; the compiled loop against the
Python step path to the last bit; Newton's failure named with the trajectory kept; the globalized iteration on the
element map's large steps against the schemes' own equations on SciPy's right-hand side and Radau."""

from __future__ import annotations

from fractions import Fraction
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from conftest import ROBOTS
from pinstab import load_scene, simulate
from pinstab.analysis import exact_reference
from pinstab.analysis.element_map import scaled_scene
from pinstab.analysis.spring_chain import scene_chain
from pinstab.errors import DivergenceError, NewtonError, PinstabError
from pinstab.integration.compiled import CompiledAdaptive, CompiledLoop, CompiledSteps
from pinstab.integration.implicit import EMBEDDED_WEIGHTS
from pinstab.integration.schemes import INTEGRATORS, embedded_pairs
from pinstab.kernels import NativeKernel, RungeKutta
from pinstab.stability.regions import stability_function

IMPLICIT = ("implicit-euler", "implicit-midpoint", "esdirk4")
OMEGA, DAMPING = 30.0, 2.0  # a = -OMEGA^2 q - DAMPING v, coordinate by coordinate


def _system(acceleration):
    """What an integrator reads of a system: its acceleration and its model's group (every joint of one coordinate)."""
    return SimpleNamespace(acceleration=acceleration, model=SimpleNamespace(euclidean=True))


def _oscillator(q, v, t, stage):
    return -(OMEGA**2) * q - DAMPING * v


F = Fraction
PUBLISHED_A = [
    [0, 0, 0, 0, 0, 0],
    [F(1, 4), F(1, 4), 0, 0, 0, 0],
    [F(8611, 62500), F(-1743, 31250), F(1, 4), 0, 0, 0],
    [F(5012029, 34652500), F(-654441, 2922500), F(174375, 388108), F(1, 4), 0, 0],
    [F(15267082809, 155376265600), F(-71443401, 120774400), F(730878875, 902184768), F(2285395, 8070912), F(1, 4), 0],
    [F(82889, 524892), 0, F(15625, 83664), F(69875, 102672), F(-2260, 8211), F(1, 4)],
]
PUBLISHED_B_HAT = [
    F(4586570599, 29645900160),
    0,
    F(178811875, 945068544),
    F(814220225, 1159782912),
    F(-3700637, 11593932),
    F(61727, 225920),
]
"""ARK4(3)6L[2]SA's implicit tableau and embedded weights as printed (Kennedy and Carpenter 2003, table of
ARK4(3)6L[2]SA: a, b = a's last row, b_hat; c = 0, 1/2, 83/250, 31/50, 17/20, 1)."""


def _order_conditions(a, b, c) -> list[Fraction]:
    """The residuals of the eight order conditions up to order 4 (Butcher's trees): sum b = 1, b.c = 1/2, b.c^2 = 1/3,
    b.Ac = 1/6, b.c^3 = 1/4, b.(c Ac) = 1/8, b.Ac^2 = 1/12, b.AAc = 1/24."""
    s = range(len(b))
    ac = [sum(a[i][j] * c[j] for j in s) for i in s]
    ac2 = [sum(a[i][j] * c[j] ** 2 for j in s) for i in s]
    aac = [sum(a[i][j] * ac[j] for j in s) for i in s]

    def dot(x):
        return sum(b[i] * x[i] for i in s)

    return [
        sum(b) - 1,
        dot(c) - Fraction(1, 2),
        dot([x**2 for x in c]) - Fraction(1, 3),
        dot(ac) - Fraction(1, 6),
        dot([x**3 for x in c]) - Fraction(1, 4),
        dot([c[i] * ac[i] for i in s]) - Fraction(1, 8),
        dot(ac2) - Fraction(1, 12),
        dot(aac) - Fraction(1, 24),
    ]


def test_esdirk_coefficients_meet_the_order_conditions():
    """Kennedy and Carpenter's ESDIRK4(3)6L[2]SA: the solution meets the 8 conditions to order 4 exactly (in
    fractions), the embedded one the 4 to order 3 and fails the order-4 ones (an order-3 estimate); the first stage is
    explicit, the diagonal 1/4, the last row of a is b (stiffly accurate), c_i = sum_j a_ij; the floats are the
    fractions to 1 ulp."""
    a, b, b_hat = PUBLISHED_A, PUBLISHED_A[5], PUBLISHED_B_HAT
    c = [sum(row) for row in a]
    assert all(residual == 0 for residual in _order_conditions(a, b, c))
    embedded = _order_conditions(a, b_hat, c)
    assert all(residual == 0 for residual in embedded[:4]) and any(residual != 0 for residual in embedded[4:])
    assert a[0] == [0] * 6 and all(a[i][i] == Fraction(1, 4) for i in range(1, 6)) and a[5] == b
    assert c == [0, F(1, 2), F(83, 250), F(31, 50), F(17, 20), 1]
    stepper = INTEGRATORS.build("esdirk4", _system(_oscillator))
    np.testing.assert_array_equal(stepper.coupling, np.array(a, dtype=float))  # each the fraction's nearest float
    np.testing.assert_array_equal(stepper.nodes, np.array(c, dtype=float))
    np.testing.assert_array_equal(stepper.weights, np.array(b, dtype=float))
    np.testing.assert_allclose(stepper.estimators[0][:6], np.array(b, float) - np.array(b_hat, float), atol=3e-16)
    assert stepper.estimators[0][6] == 0.0 and EMBEDDED_WEIGHTS == {j: float(w) for j, w in enumerate(b_hat) if w}


def _r(scheme: str, z: complex) -> complex:
    """R(z) of a registered scheme (pinstab.stability.regions, where the implicit module registers its tableaus)."""
    return complex(stability_function(scheme, z)[0])


def _exact_stability(a, b, z: Fraction) -> Fraction:
    """R(z) = 1 + z b^T (I - z a)^-1 1 in fractions (a lower triangular: forward substitution)."""
    x: list[Fraction] = []
    for i, row in enumerate(a):
        x.append((1 + z * sum(row[j] * x[j] for j in range(i))) / (1 - z * row[i]))
    return 1 + z * sum(w * xi for w, xi in zip(b, x, strict=True))


def test_esdirk_is_l_stable():
    """The registered stability functions (pinstab.stability.regions): esdirk4's |R(z)| <= 1 on the imaginary axis
    (A-stable: the left half-plane, R analytic there) and R(z) -> 0 as z -> -inf (L-stable: like 1 / z); implicit
    Euler and the midpoint rule as their closed forms 1 / (1 - z) and (1 + z/2) / (1 - z/2) (|R| = 1 on the axis: no
    damping)."""
    for y in np.geomspace(1e-3, 1e4, 200):
        assert abs(_r("esdirk4", 1j * y)) <= 1 + 1e-13
    assert abs(_r("esdirk4", -1e6)) < 1e-5
    # in exact arithmetic on the published fractions R(z) z tends to a constant: R(-inf) = 0
    far, farther = (_exact_stability(PUBLISHED_A, PUBLISHED_A[5], F(-(10**k))) for k in (9, 12))
    assert abs(farther) < 1e-10 and float(far / farther) == pytest.approx(1e3, rel=1e-6)
    for z in (-0.3 + 2j, -50.0, 4j):
        assert _r("implicit-euler", z) == pytest.approx(1 / (1 - z), rel=1e-15)
        assert _r("implicit-midpoint", z) == pytest.approx((1 + z / 2) / (1 - z / 2), rel=1e-15)


@pytest.mark.parametrize("name", IMPLICIT)
@pytest.mark.parametrize("h", [1e-3, 0.05, 2.0])
def test_steps_are_the_stability_function_of_h_a(name, h):
    """On y' = A y (a damped oscillator, omega 30 rad/s, 3 coordinates) N = 20 steps are R(h A)^N y, R the scheme's
    stability function per eigenvalue of A (closed forms for implicit Euler and the midpoint rule), to 1e-12 of |y0|,
    at |h lambda| from 0.03 to 60 (the explicit schemes' limit is 2.8 at most)."""
    stepper = INTEGRATORS.build(name, _system(_oscillator))
    a = np.array([[0.0, 1.0], [-(OMEGA**2), -DAMPING]])
    eigenvalues, vectors = np.linalg.eig(a)
    if name == "implicit-euler":
        factors = 1 / (1 - h * eigenvalues)
    elif name == "implicit-midpoint":
        factors = (1 + h * eigenvalues / 2) / (1 - h * eigenvalues / 2)
    else:
        factors = stability_function(name, h * eigenvalues)
    steps = 20
    amplification = (vectors @ np.diag(factors**steps) @ np.linalg.inv(vectors)).real
    q, v = np.array([0.3, -1.2, 2.0]), np.array([0.7, 0.1, -0.5])
    expected = amplification @ np.vstack((q, v))
    scale = np.abs(np.concatenate((q, v * h / max(h, 1 / OMEGA)))).max()
    for k in range(steps):
        q, v = stepper.step(q, v, k * h, h)
    np.testing.assert_allclose(q, expected[0], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(v, expected[1], rtol=0, atol=1e-12 * scale * OMEGA)


def test_midpoint_keeps_an_undamped_oscillator_energy():
    """With no damping the midpoint rule keeps the quadratic energy q^2 omega^2 + v^2 of a linear oscillator to
    rounding (symplectic, |R(i y)| = 1) at h omega = 3 over 1000 steps, where implicit Euler loses most of it."""

    def undamped(q, v, t, stage):
        return -(OMEGA**2) * q

    energy = {}
    for name in ("implicit-midpoint", "implicit-euler"):
        stepper = INTEGRATORS.build(name, _system(undamped))
        q, v = np.array([0.3]), np.array([2.0])
        for k in range(1000):
            q, v = stepper.step(q, v, k * 0.1, 0.1)
        energy[name] = float(OMEGA**2 * q @ q + v @ v) / (OMEGA**2 * 0.09 + 4.0)
    assert energy["implicit-midpoint"] == pytest.approx(1.0, abs=1e-9)
    assert energy["implicit-euler"] < 1e-100


def test_esdirk_is_an_embedded_pair():
    """esdirk4 is an integrator error control accepts (--rtol); implicit Euler and the midpoint rule are not."""
    pairs = embedded_pairs()
    assert "esdirk4" in pairs and "implicit-euler" not in pairs and "implicit-midpoint" not in pairs
    assert all(INTEGRATORS.build(name, _system(_oscillator)).implicit for name in IMPLICIT)
    assert not INTEGRATORS.build("rk4", _system(_oscillator)).implicit


def _error(scene, trajectory) -> float:
    """The run's largest coordinate error [rad] against the scene's exact reference from the same start."""
    exact = exact_reference(scene, trajectory.q[0], trajectory.v[0], trajectory.t)
    return float(np.abs(trajectory.q - exact.q).max())


@pytest.mark.parametrize(("name", "order"), [("implicit-euler", 1), ("implicit-midpoint", 2), ("esdirk4", 4)])
def test_convergence_order_on_the_fourbar(name, order):
    """On the four-bar (Baumgarte, over 0.5 s) halving the step divides the error against its exact reduced ODE by
    2^order within 10 %: 2, 4, 16."""
    scene = load_scene("fourbar")
    steps = {"implicit-euler": (2e-3, 1e-3), "implicit-midpoint": (4e-3, 2e-3), "esdirk4": (1e-2, 5e-3)}[name]
    errors = []
    for dt in steps:
        trajectory = simulate(scene, "baumgarte", name, dt, 0.5)
        errors.append(_error(scene, trajectory))
    ratio = errors[0] / errors[1]
    assert ratio == pytest.approx(2.0**order, rel=0.1), errors


STIFF_DURATION = 1.0


@pytest.fixture(scope="module")
def stiff():
    scene = load_scene("stiff-fourbar")
    rk4 = None
    try:
        simulate(scene, integrator="rk4", dt=5e-3, duration=STIFF_DURATION)
    except DivergenceError as error:
        rk4 = error
    return scene, rk4


def test_stiff_fourbar_at_5_ms_where_rk4_diverges(stiff):
    """stiff-fourbar at dt = 5 ms (16 times RK4's limit 0.31 ms, h lambda down to -35): RK4 diverges; the implicit
    schemes run the second without creating energy (never above the start's 8.816 J) against the Radau reference's
    (q, v, damper work W): the midpoint rule within 5e-3 rad, its energy rising by at most 1e-4 of it between samples
    (its discrete energy's O(h^2) wobble on the nonlinear spring; it damps the stiff mode only by |R(-35)| = 0.89 per
    step, not being L-stable); implicit Euler, L-stable and of order 1, damps the crank's 141 rad/s mode too (|R| =
    0.82 per step): it ends below the reference's energy E0 - W(1 s), within 0.5 rad."""
    scene, rk4 = stiff
    assert rk4 is not None and rk4.time < STIFF_DURATION
    runs = {name: simulate(scene, integrator=name, dt=5e-3, duration=STIFF_DURATION) for name in IMPLICIT[:2]}
    chain = scene_chain(scene)
    reference = chain.solve(scene.q0, scene.v0, runs["implicit-euler"].t)
    start = chain.energy(scene.q0, scene.v0)
    for run in runs.values():
        assert run.t[-1] == pytest.approx(STIFF_DURATION) and len(run.t) == len(reference)
        energy = np.array([chain.energy(q, v) for q, v in zip(run.q, run.v, strict=True)])
        np.testing.assert_allclose(run.energy, energy, rtol=0, atol=1e-12 * start)  # pinstab's energy is the chain's
        assert energy.max() <= start
        newton = run.summary()["newton"]
        assert newton["newton_iterations"] > 0 and newton["lu_factorizations"] >= 1 and newton["newton_failures"] == 0
    midpoint, euler = runs["implicit-midpoint"], runs["implicit-euler"]
    assert np.abs(midpoint.q - reference[:, :2]).max() < 5e-3
    assert np.diff(midpoint.energy).max() < 1e-4 * start
    assert np.abs(euler.q - reference[:, :2]).max() < 0.5
    assert euler.energy[-1] < start - reference[-1, 4]


def test_stiff_fourbar_esdirk_error_control(stiff):
    """esdirk4 at rtol 1e-8 over 1 s: within 1e-6 rad of the Radau reference, its mean step more than 3 times RK4's
    stability limit (0.31 ms)."""
    scene, _ = stiff
    trajectory = simulate(scene, integrator="esdirk4", dt=1e-3, duration=STIFF_DURATION, rtol=1e-8)
    assert _error(scene, trajectory) < 1e-6
    control = trajectory.info.error_control
    assert STIFF_DURATION / control["steps_accepted"] > 3 * 0.31e-3


LARGE_STEP = 1e-2  # [s]: the element map's largest step, 70 times RK4's limit at 10 times the element


def _scaled(factor: float):
    """stiff-fourbar with its spring-damper's stiffness and damping times ``factor`` (the element map's cell)."""
    return scaled_scene(load_scene("stiff-fourbar"), "rocker-spring", factor)


def _step_residuals(name: str, chain, run) -> np.ndarray:
    """Each step's residual of the scheme's own equations on the chain's ODE (SciPy's reference's right-hand side:
    Pinocchio's ABA and the spring in Python), [rad, rad/s] per coordinate: implicit Euler q1 - q0 - h v1,
    v1 - v0 - h a(q1, v1); the midpoint rule q1 - q0 - h (v0 + v1) / 2, v1 - v0 - h a((q0 + q1) / 2, (v0 + v1) / 2)."""
    h = np.diff(run.t)[:, None]
    q0, q1, v0, v1 = run.q[:-1], run.q[1:], run.v[:-1], run.v[1:]
    at_q, at_v = (q1, v1) if name == "implicit-euler" else ((q0 + q1) / 2, (v0 + v1) / 2)
    nv = q0.shape[1]
    acceleration = np.array(
        [chain.rate(0.0, np.concatenate([q, v, [0.0]]))[nv : 2 * nv] for q, v in zip(at_q, at_v, strict=True)]
    )
    return np.hstack([q1 - q0 - h * (v1 if name == "implicit-euler" else (v0 + v1) / 2), v1 - v0 - h * acceleration])


@pytest.mark.parametrize(
    ("name", "duration", "bound"), [("implicit-euler", 0.5, 0.2), ("implicit-midpoint", 0.3, 1e-2)]
)
def test_globalized_newton_solves_the_large_step(name, duration, bound):
    """stiff-fourbar with the element 10 times stiffer (fast eigenvalue -7e4 /s) at dt = 10 ms (h lambda -700), cells
    the element map predicts stable: the simplified iteration failed there (implicit Euler stopped at t = 0.27 s, the
    midpoint rule at 0.05 s after a step onto a spurious root of 3000 rad/s). Globalized, the run reaches its end,
    every step solves the scheme's own equations on the chain's ODE (an evaluation independent of the compiled
    kernel) to 1e-12 rad and 1e-9 rad/s, the motion stays within ``bound`` [rad] of SciPy's Radau (1e-12) (measured:
    0.155 rad for implicit Euler's O(h) error, 4.2e-3 rad for the midpoint rule; a spurious root is turns away), no
    energy is created, and the JSON's figures count the globalized iterations."""
    scene = _scaled(10.0)
    run = simulate(scene, integrator=name, dt=LARGE_STEP, duration=duration, limits=False)
    chain = scene_chain(scene)
    assert run.t[-1] == pytest.approx(duration)
    residuals = _step_residuals(name, chain, run)
    assert np.abs(residuals[:, :2]).max() < 1e-12 and np.abs(residuals[:, 2:]).max() < 1e-9
    reference = chain.solve(scene.q0, scene.v0, run.t)
    assert np.abs(run.q - reference[:, :2]).max() < bound
    assert np.max(run.energy) <= run.energy[0]
    newton = run.summary()["newton"]
    assert newton["globalized_iterations"] > 0 and newton["newton_failures"] == 0


def _esdirk_step(chain, q0: np.ndarray, v0: np.ndarray, h: float) -> np.ndarray:
    """One esdirk4 step of the chain's ODE (q, v) from (q0, v0), each stage's velocity increment by SciPy's hybrid
    root finder from zero (its position increment S_q + h g (v0 + Z_v) on the chain's vector space)."""
    from scipy.optimize import root

    from pinstab.integration.implicit import ESDIRK4

    nv = len(q0)

    def slope(q, v):
        return chain.rate(0.0, np.concatenate([q, v, [0.0]]))[: 2 * nv]

    slopes = [slope(q0, v0)]
    for i in range(1, len(ESDIRK4.nodes)):
        row = ESDIRK4.coupling[i]
        hg = h * row[i]
        known = sum(h * row.get(j, 0.0) * slopes[j] for j in range(i))

        def equation(zv, known=known, hg=hg):
            q = q0 + known[:nv] + hg * (v0 + zv)
            return zv - known[nv:] - hg * slope(q, v0 + zv)[nv:]

        zv = root(equation, np.zeros(nv), method="hybr", tol=1e-13).x
        assert np.abs(equation(zv)).max() < 1e-10 * (1.0 + np.abs(zv).max())  # a root (not only a stall)
        z = np.concatenate([known[:nv] + hg * (v0 + zv), zv])
        slopes.append((z - known) / hg)
    return np.concatenate([q0, v0]) + z  # stiffly accurate: the step ends on its last stage


def test_globalized_esdirk_step_is_its_stage_equations_root():
    """esdirk4 on stiff-fourbar with the element 100 times stiffer at dt = 2 ms (fast eigenvalue -7e5 /s, h lambda
    -1400), whose first step the simplified iteration left unsolved: globalized, its first step is the one SciPy's root
    finder gives on the chain's ODE stage by stage to 1e-9 (rad, rad/s), and 0.4 s run without creating energy (the
    globalized iterations counted)."""
    scene = _scaled(100.0)
    run = simulate(scene, integrator="esdirk4", dt=2e-3, duration=0.4, limits=False)
    chain = scene_chain(scene)
    first = _esdirk_step(chain, scene.q0, scene.v0, 2e-3)
    np.testing.assert_allclose(np.concatenate([run.q[1], run.v[1]]), first, rtol=0, atol=1e-9)
    assert run.t[-1] == pytest.approx(0.4) and np.max(run.energy) <= run.energy[0]
    assert run.summary()["newton"]["globalized_iterations"] > 0


def _python_steps(monkeypatch):
    """No compiled loop: every step the stepper's own (the Python step path), its Newton Jacobians from the kernel the
    compiled loop would have stepped with (lent as the loop lends them: the native kernel's analytic derivatives)."""

    def lend(system, stepper):
        CompiledLoop(system).lend_jacobians(stepper)

    patch = monkeypatch.context()
    context = patch.__enter__()
    context.setattr(CompiledSteps, "of", classmethod(lambda cls, system, stepper: lend(system, stepper)))
    context.setattr(CompiledAdaptive, "of", classmethod(lambda cls, system, stepper, pair: lend(system, stepper)))
    return patch


@pytest.mark.parametrize(
    ("scene", "name", "dt", "rtol"),
    [
        ("stiff-fourbar", "implicit-midpoint", 5e-3, None),
        ("stiff-fourbar", "esdirk4", 1e-2, 1e-7),
        ("fourbar", "implicit-euler", 1e-2, None),
        ("fourbar", "esdirk4", 1e-2, 1e-8),
        (10.0, "implicit-midpoint", LARGE_STEP, None),  # stiff-fourbar's element x 10: globalized iterations
    ],
)
def test_compiled_loop_equals_the_python_step_path(monkeypatch, scene, name, dt, rtol):
    """The compiled loop (fixed steps, error control, on the native compiled kernel) takes the same steps as the
    Python step path (the system's evaluation in Python) to the last bit, with the same Newton figures (the
    globalized iteration's too, on the cell where it runs); and two runs are the same to the last bit."""
    loaded = load_scene(scene) if isinstance(scene, str) else _scaled(scene)
    fast = simulate(loaded, "baumgarte", name, dt, 0.3, rtol=rtol)
    again = simulate(loaded, "baumgarte", name, dt, 0.3, rtol=rtol)
    patch = _python_steps(monkeypatch)
    try:
        slow = simulate(loaded, "baumgarte", name, dt, 0.3, rtol=rtol)
    finally:
        patch.__exit__(None, None, None)
    if rtol is None:  # the native kernel (with the stiff four-bar's spring-damper) evaluates the compiled steps
        assert fast.info.compiled_steps > 0
    if not isinstance(scene, str):
        assert fast.info.newton["globalized_iterations"] > 0
    assert slow.info.compiled_steps == 0
    for other in (slow, again):
        np.testing.assert_array_equal(fast.t, other.t)
        np.testing.assert_array_equal(fast.q, other.q)
        np.testing.assert_array_equal(fast.v, other.v)
        assert fast.info.newton == other.info.newton
        assert fast.info.error_control == other.info.error_control


def test_constrained_fourbar_implicit_midpoint():
    """The four-bar (one closure, Baumgarte's default gains) with the midpoint rule over 5 s at 5 and 2.5 ms: the
    drift bounded (below 1.5e-4 and 4e-5 m, ending below its largest: not growing) and falling by 4 (+-15 %) on
    halving the step, as the error against the exact reduced ODE does (order 2), which is at most half of Heun's (the
    explicit order-2 scheme) at the same step; the energy within 4e-3 and 1e-3 of its start (no damping)."""
    scene = load_scene("fourbar")
    drifts, errors = [], []
    for dt, drift_bound, energy_bound in ((5e-3, 1.5e-4, 4e-3), (2.5e-3, 4e-5, 1e-3)):
        run = simulate(scene, "baumgarte", "implicit-midpoint", dt, 5.0)
        heun = simulate(scene, "baumgarte", "heun", dt, 5.0)
        summary = run.summary()
        assert summary["final_position_drift"] < summary["max_position_drift"] < drift_bound
        drifts.append(summary["max_position_drift"])
        errors.append(_error(scene, run))
        assert errors[-1] < 0.5 * _error(scene, heun)
        assert np.abs(run.energy - run.energy[0]).max() < energy_bound * abs(run.energy[0])
    assert drifts[0] / drifts[1] == pytest.approx(4.0, rel=0.15)
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.15)


def test_newton_failure_is_named():
    """A fixed step whose stage equation has no solution (q'' = 1e6 q^2 from q = 3 at h = 10 s: implicit Euler's
    c h^2 q1^2 - q1 + q0 + h v0 = 0 has no real root) raises NewtonError (a DivergenceError: exit 3, the run's
    trajectory kept by the stepping loop) naming the scheme, the stage, the step, the scaled increment and what to
    do, after the globalized iteration tried (its iterations counted)."""
    stepper = INTEGRATORS.build("implicit-euler", _system(lambda q, v, t, stage: 1e6 * q**2))
    with pytest.raises(
        NewtonError,
        match=r"the implicit-euler step: Newton's iteration did not solve stage 1 of the step of 10 s from t = 0 s, "
        r"neither simplified nor globalized .* its last scaled increment was .* a smaller step solves it \(--dt, or "
        r"error control with --rtol\)",
    ) as caught:
        stepper.step(np.array([3.0]), np.array([0.0]), 0.0, 10.0)
    assert caught.value.time == 0.0 and isinstance(caught.value, DivergenceError)
    figures = stepper.newton_figures()
    assert figures["newton_failures"] == 1 and figures["globalized_iterations"] >= 1


def test_implicit_tableaus_are_checked():
    """A coupling above its diagonal, an implicit tableau without an explicit first stage or without Newton's
    settings are refused (ValueError, before any step)."""
    nodes, weights = np.array([0.0, 1.0]), np.array([0.0, 1.0])
    with pytest.raises(ValueError, match="above its diagonal"):
        RungeKutta(nodes, np.array([[0.0, 1.0], [0.0, 1.0]]), weights, None, (1e-10, 1e-10, 1.0, 10))
    with pytest.raises(ValueError, match="first stage must be explicit"):
        RungeKutta(nodes, np.array([[1.0, 0.0], [0.0, 1.0]]), weights, None, (1e-10, 1e-10, 1.0, 10))
    with pytest.raises(ValueError, match="needs newton"):
        RungeKutta(nodes, np.array([[0.0, 0.0], [0.0, 1.0]]), weights, None)


def test_rtol_with_a_fixed_step_implicit_scheme_is_refused():
    """--rtol needs an estimator: implicit-midpoint is refused, naming the pairs (esdirk4 among them)."""
    with pytest.raises(PinstabError, match="esdirk4"):
        simulate(load_scene("fourbar"), integrator="implicit-midpoint", dt=1e-2, duration=0.1, rtol=1e-6)


def test_newton_figures_reach_the_json_summary():
    """The run summary reports Newton's figures for an implicit run (and none for an explicit one); the error
    control's counts beside them."""
    scene = load_scene("fourbar")
    summary = simulate(scene, integrator="esdirk4", dt=1e-2, duration=0.2, rtol=1e-6).summary()
    assert set(summary["newton"]) == {
        "newton_iterations",
        "jacobian_evaluations",
        "lu_factorizations",
        "newton_failures",
        "globalized_iterations",
        "continuation_shares",
    }
    assert summary["newton"]["jacobian_evaluations"] >= 1
    assert "newton" not in simulate(scene, integrator="rk4", dt=1e-2, duration=0.2).summary()


@pytest.mark.parametrize("integrator, rtol", [("implicit-midpoint", None), ("esdirk4", 1e-6)])
def test_newton_state_carries_over_on_a_free_flyer(integrator, rtol):
    """On a model whose configuration has more coordinates than its velocity (cassie: a free flyer, nq 47, nv 44) the
    compiled step keeps its Newton state from one run of steps to the next: the falling robot's motion is a rigid
    free fall, so one Jacobian serves the whole run, and every step's stages are counted (at least one iteration per
    implicit stage: the counts were reset at every run of steps, with a fresh Jacobian each time, when the trial was
    matched to the model by nq)."""
    summary = simulate(load_scene("cassie"), integrator=integrator, dt=1e-3, duration=0.2, rtol=rtol).summary()
    newton = summary["newton"]
    implicit_stages = 1 if rtol is None else 5
    steps = 200 if rtol is None else summary["error_control"]["steps_accepted"]
    assert newton["jacobian_evaluations"] == 1
    assert newton["newton_iterations"] >= implicit_stages * steps


@pytest.mark.parametrize("name", IMPLICIT)
def test_the_criterion_knows_the_implicit_schemes(name):
    """The step-size criterion's R(tau W) of an implicit scheme: the deviation dynamics x'' = -Kp x - Kd x' have
    rho = max |R(mu)| over the roots mu of mu^2 + tau Kd mu + tau^2 Kp (R's closed form for implicit Euler and the
    midpoint rule), the matrix R(tau W) (Kronecker form) has the same radius to 1e-12, below 1 at any step for
    decaying gains (A-stable); the gains are not placed for them (PinstabError naming the way out)."""
    from pinstab.stability import criterion

    kp, kd, step = 400.0, 5.0, 0.3
    mu = np.roots([1.0, step * kd, step**2 * kp])
    closed = {
        "implicit-euler": lambda z: 1 / (1 - z),
        "implicit-midpoint": lambda z: (1 + z / 2) / (1 - z / 2),
        "esdirk4": lambda z: _r("esdirk4", z),
    }[name]
    expected = max(abs(closed(z)) for z in mu)
    assert criterion.scalar_radius(kp, kd, step, name) == pytest.approx(expected, rel=1e-12)
    matrix = criterion.amplification(np.array([[kp]]), np.array([[kd]]), np.array([True]), step, name)
    assert criterion.spectral_radius(matrix) == pytest.approx(expected, rel=1e-12)
    assert all(criterion.scalar_radius(kp, kd, tau, name) < 1.0 for tau in (1e-3, 1.0, 1e3))
    with pytest.raises(PinstabError, match="give the gains"):
        criterion.place_gains(0.01, name, 0.5)


def test_default_jacobian_is_pinocchios_derivatives():
    """Kernel.jacobian's default (forward differences of the kernel's acceleration, cpp/jacobian.cpp) on the native
    kernel of the four-bar's open chain (no closure: constraintDynamics is ABA) against Pinocchio's analytic
    computeABADerivatives at a random state: within 1e-5 of the largest entry (the differences' error is of order
    sqrt(eps) times the second derivatives)."""
    model = pin.buildModelFromUrdf(str(ROBOTS / "urdf" / "fourbar.urdf"))
    model.gravity.linear[:] = [0.0, -9.81, 0.0]
    kernel = NativeKernel(model, [], [], [], [], 0.0, 0.0, 1e-12, 1e-12, 1e-9, 100)
    rng = np.random.default_rng(0)
    q, v, tau = rng.uniform(-1, 1, model.nq), rng.uniform(-2, 2, model.nv), rng.uniform(-1, 1, model.nv)
    dadq, dadv, usable = kernel.jacobian(q, v, tau)
    data = model.createData()
    pin.computeABADerivatives(model, data, q, v, tau)
    assert usable
    np.testing.assert_allclose(dadq, data.ddq_dq, rtol=0, atol=1e-5 * np.abs(data.ddq_dq).max())
    np.testing.assert_allclose(dadv, data.ddq_dv, rtol=0, atol=1e-5 * np.abs(data.ddq_dv).max())
