"""The corrections of ``projection`` and ``post`` (``cpp/projection.cpp``): the least-change correction against NumPy's
least squares; the Gauss-Newton projection against the closed form of a point on a circle; on the core path the
compiled loop's corrections against the Python path's (pinstab's rows in Python, the general projector, the Python
step loop), positions on the manifold after each step; a projection that cannot converge named with its time and
residual, the run keeping what it computed."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from conftest import kicked_cassie, pinocchio_closure_residuals
from pinstab import assemble, build_system, load_scene, simulate
from pinstab.errors import DivergenceError, ProjectionError
from pinstab.integration.compiled import CompiledSteps, compiled_obstacle
from pinstab.integration.schemes import INTEGRATORS
from pinstab.kernels import weighted_correction as compiled_correction
from pinstab.projection import CUTOFF, GeneralProjector, project_positions, weighted_correction
from pinstab.system import ConstrainedSystem

ON_MANIFOLD = 1e-12  # [m or rad]: max |phi| after each step of `projection` (its tolerance 1e-13 per m of size)


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    factor = rng.standard_normal((n, n))
    return factor @ factor.T + n * np.eye(n)


def _lstsq_correction(mass: np.ndarray, jacobian: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """-M^-1 G^T (G M^-1 G^T)^+ r by NumPy: the inverse and LAPACK's least squares (rcond: the cutoff)."""
    spread = np.linalg.solve(mass, jacobian.T)
    return -spread @ np.linalg.lstsq(jacobian @ spread, residual, rcond=CUTOFF)[0]


@pytest.mark.parametrize("redundant", [False, True])
def test_the_least_change_correction_is_numpys_least_squares_one(redundant):
    """Random M (SPD, 12 x 12), G (5 rows; redundant: the last two repeat the first two, rank 3) and r (consistent
    with the rows when they are redundant): the compiled correction equals NumPy's to 1e-12 relative, removes r to
    first order (G dq = -r) and is M-orthogonal to the rows' null space (the least change in the kinetic metric)."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        mass, jacobian = _spd(rng, 12), rng.standard_normal((5, 12))
        if redundant:
            jacobian[3:] = jacobian[:2]
        residual = jacobian @ rng.standard_normal(12)
        change = weighted_correction(mass, jacobian, residual)
        expected = _lstsq_correction(mass, jacobian, residual)
        np.testing.assert_allclose(change, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
        np.testing.assert_allclose(jacobian @ change, -residual, rtol=0, atol=1e-11 * np.abs(residual).max())
        null = np.linalg.svd(jacobian)[2][np.linalg.matrix_rank(jacobian) :]
        assert np.abs(null @ (mass @ change)).max() <= 1e-11 * np.abs(mass @ change).max()


def test_the_refined_correction_is_the_least_squares_one_of_the_square_root():
    """Random M (SPD, 12 x 12) and G (6 rows) with singular values of G L^-T down to 1e-9 of the largest (M = L L^T),
    r in the rows' range: G M^-1 G^T's pseudo-inverse drops the near-singular directions (more than 1e-6 of r left);
    refined, the correction equals NumPy's least-norm solution of the square root's rows, -L^-T lstsq(G L^-T, r), to
    1e-6 relative (its entries reach 1e9 |r|: conditioning, not the method, bounds the agreement) and leaves of
    G dq + r only the rounding of G dq (16 eps |G| |dq|); where nothing is dropped (a well-conditioned G) refining
    changes no bit."""
    rng = np.random.default_rng(5)
    mass = _spd(rng, 12)
    factor = np.linalg.cholesky(mass)
    left, _, right = np.linalg.svd(rng.standard_normal((6, 12)), full_matrices=False)
    root = left @ np.diag([1.0, 0.8, 0.5, 1e-3, 1e-7, 1e-9]) @ right  # G L^-T
    jacobian = root @ factor.T
    residual = left @ rng.standard_normal(6)  # in the rows' range, along every singular direction
    plain = weighted_correction(mass, jacobian, residual)
    assert np.abs(jacobian @ plain + residual).max() > 1e-6 * np.abs(residual).max()
    refined = weighted_correction(mass, jacobian, residual, refine=True)
    expected = -np.linalg.solve(factor.T, np.linalg.lstsq(root, residual, rcond=CUTOFF)[0])
    np.testing.assert_allclose(refined, expected, rtol=0, atol=1e-6 * np.abs(expected).max())
    rounding = 16 * np.finfo(float).eps * (np.abs(jacobian) @ np.abs(refined)).max()
    assert np.abs(jacobian @ refined + residual).max() <= rounding < 1e-6 * np.abs(residual).max()
    well = rng.standard_normal((6, 12))
    plain, refined = (weighted_correction(mass, well, residual, refine=on) for on in (False, True))
    assert np.array_equal(plain, refined)


def test_a_correction_of_rows_not_finite_is_a_projection_error():
    """NaN rows, rows whose G M^-1 G^T overflows (1e200: D = 3e400, whose pseudo-inverse would be 0, no change) or an
    M that is not positive definite: a ProjectionError (the compiled rule says so), not NaN nor a zero change."""
    mass, jacobian = np.eye(3), np.ones((1, 3))
    change, finite = compiled_correction(mass, jacobian * np.nan, np.ones(1), CUTOFF)
    assert not finite and np.isnan(change).all()
    change, finite = compiled_correction(mass, jacobian * 1e200, np.ones(1), CUTOFF)
    assert not finite and np.isnan(change).all()
    with pytest.raises(ProjectionError, match="overflow"):
        weighted_correction(mass, jacobian * 1e200, np.ones(1))
    with pytest.raises(ProjectionError, match="not finite"):
        weighted_correction(mass, jacobian * np.nan, np.ones(1))
    with pytest.raises(ProjectionError, match="positive definite"):
        weighted_correction(-mass, jacobian, np.ones(1))


class _Circle:
    """A point (x, y) of isotropic mass on the circle x^2 + y^2 = R^2 (one row, G = 2 (x, y)), as a projector."""

    radius = 0.7

    def position_step(self, q: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        phi = np.array([q @ q - self.radius**2])
        return weighted_correction(2.5 * np.eye(2), 2.0 * q[None, :], phi), float(abs(phi[0]))

    def velocity_projection(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        return v + weighted_correction(2.5 * np.eye(2), 2.0 * q[None, :], np.array([2.0 * q @ v]))


class _Model:
    """What project_positions reads of a ConstrainedModel, for the two coordinates of the circle's point."""

    def __init__(self) -> None:
        import pinocchio as pin

        self.model = pin.Model()
        for axis in (pin.JointModelPX(), pin.JointModelPY()):
            self.model.addJoint(self.model.njoints - 1, axis, pin.SE3.Identity(), "x" if self.model.nq == 0 else "y")

    def position_tolerance(self, tolerance: float) -> float:
        return tolerance


def test_gauss_newton_reaches_the_nearest_point_of_a_circle():
    """Isotropic mass: the kinetic metric's nearest point of the circle is the radial one, R q / |q|; the compiled
    Gauss-Newton iteration (a Python projector called back) reaches it to 1e-15 (rounding) in a few steps, and
    stops within its iteration limit or says it did not converge."""
    model, circle = _Model(), _Circle()
    for start in (np.array([1.0, 0.4]), np.array([-0.2, 0.3]), np.array([0.05, -0.9])):
        q, iterations = project_positions(model, circle, start, 0.0, 1e-13, 20)
        np.testing.assert_allclose(q, circle.radius * start / np.linalg.norm(start), rtol=0, atol=1e-15)
        assert 1 <= iterations <= 8
    with pytest.raises(ProjectionError, match=r"did not converge: residual .* after 2 iterations at t = 0.25 s"):
        project_positions(model, circle, np.array([3.0, 4.0]), 0.25, 1e-13, 2)


def _python_path(patch) -> None:
    """The correction in Python: pinstab's rows and the general projector, the Python step loop."""
    bind = ConstrainedSystem.bind

    def python_bind(self, *arguments, **keywords):
        bind(self, *arguments, **keywords)
        self.projector = GeneralProjector(self.model)

    patch.setattr(ConstrainedSystem, "bind", python_bind)
    patch.setattr(CompiledSteps, "of", classmethod(lambda cls, system, stepper: None))


@pytest.mark.parametrize("method", ["projection", "post"])
@pytest.mark.parametrize(
    ("scene_name", "path", "duration", "integrator"),
    [
        ("fourbar", "native", 0.2, "rk4"),
        ("delta", "core", 0.2, "rk4"),
        ("delta", "core", 0.2, "dopri5"),
        ("cassie", "core", 0.05, "rk4"),
    ],
)
def test_the_compiled_correction_is_the_python_one(monkeypatch, scene_name, path, duration, integrator, method):
    """The run with its corrections compiled (the core path: in the compiled loop, a scheme's steps or a tableau's,
    dopri5 without error control; the native path: Pinocchio's projector called back by the compiled rule) equals the
    Python path's (pinstab's rows, the general projector, the Python loop) to 1e-12 in q and 1e-10 in v (their
    M^-1 G^T and G v + g_t are summed in other orders; measured: equal to the last bit on fourbar, 3e-15 in q and
    1.1e-13 in v on delta over 0.2 s by RK4, 1.6e-14 and 1.6e-13 by dopri5, 1e-25 on cassie over 0.05 s, whose free
    fall RK4 keeps on its manifold to 3e-15 m: no Gauss-Newton iteration needed), with the same correction iterations;
    `projection` leaves every step on the manifold to ON_MANIFOLD."""
    scene = load_scene(scene_name)
    compiled = simulate(scene, method, integrator, 1e-3, duration)
    with monkeypatch.context() as patch:
        _python_path(patch)
        python = simulate(scene, method, integrator, 1e-3, duration)
    assert compiled.info.path == python.info.path == path
    assert python.info.compiled_steps == 0
    if path == "core":
        assert compiled.info.compiled_steps >= 0.9 * len(compiled.t)
    np.testing.assert_allclose(compiled.q, python.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.v, python.v, rtol=0, atol=1e-10)
    assert compiled.info.correction_iterations_total == python.info.correction_iterations_total
    if method == "projection":
        assert np.max(compiled.position_drift) <= ON_MANIFOLD


def test_a_projection_that_cannot_converge_names_its_time_and_keeps_the_run(monkeypatch):
    """One Gauss-Newton iteration allowed and a tolerance below rounding: the compiled loop cannot correct the first
    step, hands it to the Python step, whose correction (the same rule) raises the ProjectionError naming t, the
    residual and the remedy; the run stops there with the states it computed."""
    scene = load_scene("delta")
    with pytest.raises(DivergenceError) as caught:
        simulate(scene, "projection", "rk4", 1e-3, 0.05, tolerance=1e-30, max_iterations=1)
    message = str(caught.value)
    assert "coordinate projection did not converge" in message and "at t = 0.001 s" in message
    assert "Reduce dt or use another method" in message
    assert caught.value.trajectory is not None and len(caught.value.trajectory.t) >= 1


def test_the_compiled_loop_corrects_on_the_core_path_only():
    """`projection` on the core path (delta): the compiled loop takes its fixed steps, a scheme's and a tableau's (no
    obstacle); its error-controlled steps stay in Python, and off the core path (the four-bar's native path) so do
    its fixed steps, each reason named."""
    scene = load_scene("delta")
    system = build_system(scene, "projection")
    system.bind(1e-3, "rk4", scene.q0)
    assert system.path == "core"
    assert compiled_obstacle(system, INTEGRATORS.build("rk4", system)) is None
    assert compiled_obstacle(system, INTEGRATORS.build("dopri5", system)) is None
    reason = compiled_obstacle(system, INTEGRATORS.build("dop853", system), adaptive=True)
    assert reason == "method projection corrects the accepted steps of error control (in Python)"
    fourbar = load_scene("fourbar")
    system = build_system(fourbar, "post")
    system.bind(1e-3, "rk4", fourbar.q0)
    assert system.path == "native"
    reason = compiled_obstacle(system, INTEGRATORS.build("rk4", system))
    assert reason == "method post corrects the state after each step (compiled on the core path only)"


@pytest.mark.parametrize("compiled", [False, True])
def test_the_position_projection_converges_on_near_singular_closures(compiled):
    """Cassie kicked at its left knee motor (benchmarks/cassie_implicit.py), moved along its start velocity for 1 to
    20 ms (a step's free motion: closure residuals 1.4e-9 to 5.4e-7 m): its shin and heel-spring triangles are
    near-singular, G M^-1 G^T's pseudo-inverse drops their directions and Gauss-Newton by it alone stalls (at 3e-13 to
    1.3e-10 m after 20 iterations, measured); with the least change refined by the singular values of G L^-T the
    projection, by pinstab's rows in Python (the general projector, the passage guard's) and by the core's compiled
    ones, converges in 20 iterations: Pinocchio's residual of every closure at most 1e-14 m or rad."""
    scene = kicked_cassie()
    system = build_system(scene, "projection")
    start = assemble(system.model, scene.q0, scene.v0)
    system.bind(5e-3, "rk4", start.q)
    assert system.path == "core"
    projector = system.projector if compiled else GeneralProjector(system.model)
    for h in (1e-3, 5e-3, 2e-2):
        moved = pin.integrate(system.model.model, start.q, h * start.v)
        assert np.abs(pinocchio_closure_residuals(system.model, moved, start.v)[0]).max() >= 1e-9
        q, iterations = project_positions(system.model, projector, moved, 0.0, 1e-13, 20)
        assert iterations <= 20
        assert np.abs(pinocchio_closure_residuals(system.model, q, start.v)[0]).max() <= 1e-14
