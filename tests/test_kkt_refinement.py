"""The KKT solve near a singular configuration: the core's (and the general path's direct) solve against the solver
``extended`` (the whole KKT system, refined in extended precision), an independent reference that forms no Delassus
matrix."""

from __future__ import annotations

import numpy as np
import pytest

from pinstab import load_scene, simulate
from pinstab.solvers import ExtendedSolver
from pinstab.solvers.base import KKTProblem
from pinstab.system import build_system

# delta's configuration at t = 0.875 s: the KKT matrix's condition number ~1e5, the Delassus matrix's smallest
# eigenvalue 5e-10 of its largest (without refinement the core's accelerations were 1.5e-9 off, relative)
SINGULAR_TIME = 0.875  # [s]
RELATIVE = 1e-11  # measured 3e-12


@pytest.fixture(scope="module")
def near_singular():
    scene = load_scene("delta")
    run = simulate(scene, duration=1.0)
    k = int(np.argmin(np.abs(run.t - SINGULAR_TIME)))
    system = build_system(scene)
    system.bind(scene.step or 1e-3, "rk4", scene.q0)
    assert system.path == "core"
    return system, run.t[k], run.q[k], run.v[k]


def _problem(system, t, q, v) -> KKTProblem:
    model = system.model
    terms = model.dynamics_terms(q, v, t)
    values = terms.values
    rhs = -values.drift + system.stabilizer.stabilization_term(model, q, v, t, values, 0)
    return KKTProblem(
        q, v, t, terms.tau, terms.mass_matrix, terms.tau - terms.bias, values.jacobian, rhs, model.constraints.layout
    )


def test_the_core_solve_near_a_singular_configuration_is_the_extended_solve(near_singular):
    system, t, q, v = near_singular
    problem = _problem(system, t, q, v)
    reference = ExtendedSolver().solve(problem).acceleration
    spectrum = np.linalg.eigvalsh(problem.jacobian @ np.linalg.solve(problem.mass_matrix, problem.jacobian.T))
    assert spectrum[0] / spectrum[-1] < 1e-8  # the rows nearly dependent here
    core = system.acceleration(q, v, t, 0)
    assert np.abs(core - reference).max() <= RELATIVE * np.abs(reference).max()


def test_the_general_path_solve_near_a_singular_configuration_is_the_extended_solve(near_singular):
    system, t, q, v = near_singular
    problem = _problem(system, t, q, v)
    reference = ExtendedSolver().solve(problem).acceleration
    general = build_system(load_scene("delta"), solver="proxsuite")
    general.bind(1e-3, "rk4", q)
    # ProxQP (the rows fail the direct solve's margin here) is 1.2e-10 off; the direct solve, one step earlier, within
    # RELATIVE: both measured against the same reference
    solution = general.solver.solve(problem)
    assert np.abs(solution.acceleration - reference).max() <= 1e-9 * np.abs(reference).max()


def test_the_extended_solver_on_a_regular_state_is_the_dense_solve():
    """Away from singular configurations the two agree to rounding; the extended solve's primal residual is nil."""
    scene = load_scene("fourbar")
    system = build_system(scene, solver="dense")
    system.bind(1e-3, "rk4", scene.q0)
    v = np.full(system.model.nv, 0.7)
    problem = _problem(system, 0.0, scene.q0, v)
    dense, extended = system.solver.solve(problem), ExtendedSolver().solve(problem)
    np.testing.assert_allclose(
        extended.acceleration, dense.acceleration, rtol=0, atol=1e-12 * np.abs(dense.acceleration).max()
    )
    np.testing.assert_allclose(
        extended.multipliers, dense.multipliers, rtol=0, atol=1e-11 * np.abs(dense.multipliers).max()
    )
    assert extended.primal_residual <= 1e-15
