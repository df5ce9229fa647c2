"""The core path (``cpp/core_rows.cpp``, ``cpp/core_kernel.cpp``, :mod:`pinstab.paths.core`): each standard row kind's
Jacobian and drift against finite differences of its residual; the KKT solve with redundant rows against the
pseudo-inverse solution; the compiled loop on the configuration group against the Python loop to the last bit; the
full Cassie at 1 ms against the same method at 0.1 ms and the general path (ProxQP) on the same scene."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest

from pinstab import build_system, load_scene, simulate
from pinstab.errors import SolverLimitWarning
from pinstab.integration.compiled import SCHEMES, CompiledSteps
from pinstab.kinematics import Kinematics
from pinstab.solvers.base import ACCEPTED_RESIDUAL, KKTProblem, primal_residual

STEP = 1e-5  # [rad or m per unit of v]: central differences, error ~ STEP^2 |phi'''| + rounding / STEP


def _blocks_by_kind(scene_name: str) -> dict[str, object]:
    scene = load_scene(scene_name)
    return scene, {constraint.kind: constraint for constraint in scene.constraints}


def _state(scene, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A configuration near the scene's start (not on its constraints: the rows' derivatives hold anywhere) and a
    velocity, both random."""
    rng = np.random.default_rng(seed)
    q = pin.integrate(scene.model, scene.q0, 0.2 * rng.standard_normal(scene.model.nv))
    return q, rng.standard_normal(scene.model.nv)


def _residual(kin: Kinematics, constraint, q: np.ndarray) -> np.ndarray:
    kin.update_positions(q)
    return constraint.residual(kin, q, 0.0)


@pytest.mark.parametrize(
    ("scene_name", "kind"),
    [("cassie", "point"), ("cassie", "revolute"), ("cassie", "prismatic"), ("cassie", "joint-relation"),
     ("delta", "weld"), ("fourbar", "planar-point")],
)  # fmt: skip
def test_each_row_kinds_jacobian_and_drift_are_its_residuals_derivatives(scene_name, kind):
    """G v = d/de phi(q (+) e v) and gamma0 = d2/de2 phi(q (+) e v) (the drift at zero acceleration, v constant in the
    tangent space), both by central differences, at random states off the constraints."""
    scene, blocks = _blocks_by_kind(scene_name)
    constraint, model = blocks[kind], scene.model
    kin = Kinematics(model, model.createData())
    for seed in range(3):
        q, v = _state(scene, seed)
        plus, centre, minus = (_residual(kin, constraint, pin.integrate(model, q, e * v)) for e in (STEP, 0.0, -STEP))
        kin.update(q, v)
        jacobian, time_term = constraint.velocity_terms(kin, q, 0.0)
        drift = constraint.drift(kin, q, v, 0.0)
        scale = 1.0 + np.abs(jacobian @ v).max()
        np.testing.assert_allclose(jacobian @ v, (plus - minus) / (2 * STEP), rtol=0, atol=1e-8 * scale)
        np.testing.assert_allclose(time_term, 0.0, atol=0)
        np.testing.assert_allclose(drift, (plus - 2 * centre + minus) / STEP**2, rtol=0, atol=1e-4 * scale)


def test_the_core_solve_of_redundant_rows_is_the_pseudo_inverse_solution():
    """The full Cassie's 36 rows are redundant (rank 28 at its start): the kernel's pseudo-inverse gives the least-norm
    multipliers' accelerations, a = M^-1 (f + G^T pinv(G M^-1 G^T) (rhs - G M^-1 f)) (NumPy's pinv: LAPACK's SVD, rcond
    1e-12, the kernel's cutoff), at a moving state."""
    scene = load_scene("cassie")
    system = build_system(scene)
    system.bind(1e-3, "rk4", scene.q0)
    assert system.path == "core"
    rng = np.random.default_rng(7)
    terms = system.model.dynamics_terms(scene.q0, np.zeros(scene.model.nv), 0.0)
    jacobian = terms.values.jacobian
    _, singular, rows = np.linalg.svd(jacobian)
    rank = int(np.sum(singular > 1e-9 * singular[0]))
    assert rank < jacobian.shape[0]
    v = rows[rank:].T @ rng.standard_normal(scene.model.nv - rank)  # a velocity the closures allow
    terms = system.model.dynamics_terms(scene.q0, v, 0.0)
    values = terms.values
    rhs = -values.drift - 20.0 * values.velocity_residual - 100.0 * values.phi
    mass, force = terms.mass_matrix, terms.tau - terms.bias
    free, spread = np.linalg.solve(mass, force), np.linalg.solve(mass, values.jacobian.T)
    multipliers = np.linalg.pinv(values.jacobian @ spread, rcond=1e-12) @ (rhs - values.jacobian @ free)
    expected = free + spread @ multipliers
    acceleration = system.acceleration(scene.q0, v, 0.0, 0)
    assert system.statistics.status_counts == {"core pseudo-inverse": 1}
    np.testing.assert_allclose(acceleration, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    # what G a = rhs misses is the near-singular shin-spring rows' part that the cutoff leaves out (1.1e-6 m/s^2 of
    # 447 here), well within what an evaluation must reach
    problem = KKTProblem(
        scene.q0, v, 0.0, terms.tau, mass, force, values.jacobian, rhs, system.model.constraints.layout
    )
    assert primal_residual(problem, acceleration) <= ACCEPTED_RESIDUAL


@pytest.mark.parametrize("integrator", list(SCHEMES))
def test_the_compiled_loop_on_the_group_equals_the_python_loop(monkeypatch, integrator):
    """Cassie (a free flyer, two balls, joint springs): the compiled loop's steps on the configuration group
    (pinocchio::integrate, dDifference) are the Python loop's to the last bit."""
    scene = load_scene("cassie")
    fast = simulate(scene, "baumgarte", integrator, 1e-3, 0.05)
    with monkeypatch.context() as patch:
        patch.setattr(CompiledSteps, "of", classmethod(lambda cls, system, stepper: None))
        slow = simulate(scene, "baumgarte", integrator, 1e-3, 0.05)
    assert fast.info.path == slow.info.path == "core"
    assert fast.info.compiled_steps > 0 and slow.info.compiled_steps == 0
    np.testing.assert_array_equal(fast.q, slow.q)
    np.testing.assert_array_equal(fast.v, slow.v)


def test_full_cassie_at_one_millisecond_on_the_core():
    """The full Cassie (16 closures, 10 redundant rows, floating base, free fall) at 1 ms on the core: drift <= 1e-8
    m over 0.5 s, energy balance <= 1e-6 of its energy, within 1e-8 rad of the same method at 0.1 ms (RK4: the
    error falls as dt^4) and of the general path (ProxQP) over 0.02 s."""
    scene = load_scene("cassie")
    run = simulate(scene, "baumgarte", "rk4", 1e-3, 0.5)
    fine = simulate(scene, "baumgarte", "rk4", 1e-4, 0.5, record_every=10)
    assert run.info.path == "core" and run.info.solver_statistics.fallbacks == 0
    assert np.max(run.position_drift) <= 1e-8
    energy = run.energy
    assert abs(energy[-1] - energy[0]) <= 1e-6 * abs(energy[0])
    np.testing.assert_allclose(fine.t, run.t, rtol=0, atol=1e-12)
    assert np.max(np.abs(fine.q - run.q)) <= 1e-8
    general = simulate(scene, "baumgarte", "rk4", 1e-3, 0.02, solver="proxsuite")
    assert general.info.path == "general"
    assert np.max(np.abs(general.q - run.q[: len(general.q)])) <= 1e-8


@pytest.mark.parametrize(
    ("scene_name", "named"),
    [
        ("finger-rolling", "constraint(s) tip, tip/rolling evaluated in Python"),
        ("rolling-disk", "constraint(s) floor evaluated in Python"),
        ("dual-panda-box", "force(s) carry evaluated in Python"),
        ("allegro-lift", "force(s) lift evaluated in Python"),
        ("allegro-box", ""),
    ],
)
def test_blocks_and_forces_without_compiled_forms_run_on_the_core_from_python(scene_name, named):
    """Rolling contacts (holonomic and Pfaffian rows), an object-level grasp controller, soft fingers: the core takes
    them (the Python part's rows and forces at each evaluation, named in the path's reason) and its trajectory over
    0.3 s is the general path's (ProxQP's direct solve, the same rows) to 1e-10 in q and v (measured: 6e-15 .. 5e-13
    in q, 4e-14 .. 1e-11 in v over 2 s)."""
    scene = load_scene(scene_name)
    core = simulate(scene, duration=0.3, progress=False)
    general = simulate(scene, duration=0.3, progress=False, solver="proxsuite")
    assert (core.info.path, general.info.path) == ("core", "general")
    assert named in core.info.path_reason
    assert core.info.compiled_steps > 0 and core.info.solver_statistics.fallbacks == 0
    np.testing.assert_allclose(core.q, general.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(core.v, general.v, rtol=0, atol=1e-10)


def test_proxqp_at_its_iteration_limit_is_a_warning():
    """The full Cassie on the general path (solver proxsuite named): ProxQP stops at its iteration limit on every solve
    (the near-singular shin-spring rows), each accepted by its residual; the run says so instead of staying silent,
    and the core path, which takes those rows by a pseudo-inverse, gives no such warning."""
    scene = load_scene("cassie")
    with pytest.warns(SolverLimitWarning, match=r"iteration limit on 8 of 8 solves"):
        general = simulate(scene, duration=0.002, solver="proxsuite", progress=False)
    assert general.info.solver_statistics.status_counts == {"PROXQP_MAX_ITER_REACHED": 8}
    with warnings.catch_warnings():
        warnings.simplefilter("error", SolverLimitWarning)
        simulate(scene, duration=0.002, progress=False)
