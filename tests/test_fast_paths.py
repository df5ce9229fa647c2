"""The shortcuts of the grasp, rolling and servo runs (issue 23) against the computations they replace:
values computed once per kinematics update against a fresh pass at the new state, LAPACK's SVD and
pseudo-inverse against numpy's, the float cone test against ``leaving``, warm-started QPs against cold ones,
g(q) from the full pass against Pinocchio's RNEA, the one-row servo solve against the pseudo-inverse."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pinocchio as pin
import pytest

from pinstab import load_scene
from pinstab.actuation import Actuation
from pinstab.grasp.analysis import GraspContact
from pinstab.grasp.holding import (
    FEASIBILITY,
    ConeTest,
    WarmQP,
    cone_columns,
    cone_margins,
    feasible,
)
from pinstab.grasp.linalg import closest_solution, pinv, svd
from pinstab.kinematics import Kinematics
from pinstab.model import ConstrainedModel
from pinstab.servo import ServoSolver


def leaving(contacts, forces: np.ndarray) -> dict[str, dict[str, float]]:
    """The reference the compiled cone test is checked against: every contact with a margin (:func:`cone_margins`,
    written in Python from each contact model's limits) below the rounding slack, with those margins."""
    slack = -FEASIBILITY * (1.0 + float(np.max(np.abs(forces), initial=0.0)))
    found = {}
    for name, margins in cone_margins(contacts, forces).items():
        violated = {key: value for key, value in margins.items() if value < slack}
        if violated:
            found[name] = violated
    return found


RNG = np.random.default_rng(23)


@pytest.fixture(scope="module")
def sphere() -> ConstrainedModel:
    return ConstrainedModel(load_scene("allegro-sphere"))


def moved(model: ConstrainedModel, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """A state near the scene's start: (q, v)."""
    q = pin.integrate(model.model, model.scene.q0, scale * RNG.normal(size=model.nv))
    return q, scale * RNG.normal(size=model.nv)


def fresh_values(model: ConstrainedModel, q: np.ndarray, v: np.ndarray):
    """The constraint values at (q, v) from a Kinematics of its own (nothing cached from another state)."""
    kin = Kinematics(model.model)
    kin.update(q, v)
    return model.constraints.values(kin, q, v, 0.0, with_drift=True)


@pytest.mark.parametrize("scene", ["allegro-sphere", "finger-rolling"])
def test_rows_cached_per_update_follow_the_state(scene):
    """Rows, residuals and drifts read twice at one state, then at a second state, equal a fresh pass at
    each state (1e-13): what is kept for an update is not served after the next."""
    model = ConstrainedModel(load_scene(scene))
    for scale in (1e-3, 2e-3):
        q, v = moved(model, scale)
        model.kin.update(q, v)
        first = model.constraints.values(model.kin, q, v, 0.0, with_drift=True)
        again = model.constraints.values(model.kin, q, v, 0.0, with_drift=True)
        fresh = fresh_values(model, q, v)
        for name in ("phi", "jacobian", "drift"):
            expected = getattr(fresh, name)
            assert np.abs(getattr(first, name) - expected).max() <= 1e-13 * max(1.0, np.abs(expected).max())
            assert np.array_equal(getattr(again, name), getattr(first, name))


def test_gravity_from_the_full_pass_is_pinocchios(sphere):
    """Kinematics.gravity() after a full update and after a positions-only one equals
    ``computeGeneralizedGravity`` at that q (1e-12 N m)."""
    kin = Kinematics(sphere.model)
    for update in (lambda q, v: kin.update(q, v), lambda q, v: kin.update_positions(q)):
        q, v = moved(sphere, 0.05)
        update(q, v)
        expected = pin.computeGeneralizedGravity(sphere.model, sphere.model.createData(), q)
        assert np.abs(kin.gravity() - expected).max() < 1e-12


@pytest.mark.parametrize("shape", [(6, 12), (12, 16), (4, 4), (3, 7)])
def test_lapack_svd_and_pseudo_inverse_are_numpys(shape):
    """svd and pinv through LAPACK equal numpy's (1e-13), on full-rank and rank-deficient matrices."""
    full = RNG.normal(size=shape)
    deficient = full.copy()
    deficient[-1] = deficient[0] - 2.0 * deficient[1]
    for matrix in (full, deficient, np.zeros(shape)):
        for ours, theirs in zip(svd(matrix, full=False), np.linalg.svd(matrix, full_matrices=False), strict=True):
            assert np.abs(np.abs(ours) - np.abs(theirs)).max() < 1e-13
        assert np.abs(pinv(matrix) - np.linalg.pinv(matrix)).max() < 1e-13 * max(1.0, np.abs(pinv(matrix)).max())


def test_float_cone_test_is_leaving(sphere):
    """ConeTest.holds agrees with ``not leaving(...)`` on forces inside, on and outside the cones, and refuses NaN."""
    contacts = sphere.constraints.constraints
    test = ConeTest(contacts)
    inside = np.tile([0.1, -0.2, 1.0], len(contacts))
    samples = [inside, np.zeros_like(inside)]
    for _ in range(300):
        forces = inside + RNG.normal(scale=0.6, size=inside.size)
        samples.append(forces)
    edge = inside.copy()
    edge[:2] = [0.8, 0.0]  # |f_t| = mu f_n on the first contact
    samples += [edge, edge * np.array([1.0 + 1e-6] + [1.0] * (edge.size - 1))]
    verdicts = [test.holds(forces) for forces in samples]
    assert verdicts == [not leaving(contacts, forces) for forces in samples]
    assert any(verdicts) and not all(verdicts)
    nan = inside.copy()
    nan[0] = np.nan
    assert not test.holds(nan)


def test_cone_test_keeps_soft_fingers_torsion_and_the_cap():
    """The compiled cone test (the core's hold's too) on a mix of contact models agrees with ``not leaving(...)`` on
    forces inside, on and outside every limit, a soft finger's torsion |m_z| <= torsion f_n included, and with a
    cap on the normal forces [N] (1e-9 relative over it refused); stacked forces of another size are refused."""
    models = ["soft-finger", "point-friction", "frictionless", "rigid", "soft-finger"]
    contacts = [
        GraspContact(f"c{k}", model, np.zeros(3), np.eye(3), mu=0.5, torsion=0.02) for k, model in enumerate(models)
    ]
    count = cone_columns(contacts)[1]
    test, capped = ConeTest(contacts), ConeTest(contacts, cap=1.5)
    columns = cone_columns(contacts)[0]
    normals, spins = [c.normal for c in columns], [c.spin for c in columns if c.spin is not None]
    spin = spins[0]
    inside, scales = np.zeros(count), np.full(count, 0.3)
    inside[normals], scales[spins] = 1.0, 0.01  # moments [N m] on the scale of torsion f_n
    samples = [inside] + [inside + scales * RNG.normal(size=count) for _ in range(300)]
    for factor in (1.0, 1.0 + 1e-6):
        twisted = inside.copy()
        twisted[spin] = 0.02 * factor  # on the torsion limit, then beyond it
        samples.append(twisted)
    verdicts = [test.holds(forces) for forces in samples]
    assert verdicts == [not leaving(contacts, forces) for forces in samples]
    assert verdicts[-2] and not verdicts[-1] and any(verdicts[1:-2]) and not all(verdicts[1:-2])
    within = [float(np.max(forces[normals])) <= 1.5 * (1.0 + 1e-9) for forces in samples]
    assert [capped.holds(forces) for forces in samples] == [v and w for v, w in zip(verdicts, within, strict=True)]
    assert not all(within)
    with pytest.raises(ValueError, match="a column outside the forces"):
        test.holds(inside[:-1])


def test_warm_started_qp_is_the_cold_one():
    """A sequence of drifting QPs with active inequalities: each warm solve (on the previous active set, else
    ProxQP warm-started) equals a cold solve to 1e-8, and takes no more ProxQP iterations in all (none for a
    solve on the active set)."""
    size, equalities, inequalities = 8, 2, 6
    hessian_root = RNG.normal(size=(size, size))
    base = (hessian_root @ hessian_root.T + size * np.eye(size), RNG.normal(size=size))
    equality, rhs = RNG.normal(size=(equalities, size)), RNG.normal(size=equalities)
    inequality = RNG.normal(size=(inequalities, size))
    lower, upper = np.full(inequalities, -0.2), np.full(inequalities, 0.2)
    warm, warm_iterations, cold_iterations = WarmQP(), 0, 0
    for k in range(20):
        hessian, gradient = base[0], base[1] + 0.01 * k
        ours, solved, info = warm.solve(hessian, gradient, equality, rhs, inequality, lower, upper)
        cold, cold_solved, cold_info = WarmQP().solve(hessian, gradient, equality, rhs, inequality, lower, upper)
        assert solved and cold_solved
        assert np.abs(ours - cold).max() < 1e-8
        assert np.any(np.isclose(np.abs(inequality @ cold), 0.2, atol=1e-8))  # some bound is active
        warm_iterations += info.iter if k and info is not None else 0
        cold_iterations += cold_info.iter if k else 0
    assert warm_iterations <= cold_iterations


def test_screened_qp_fails_at_once_and_solves_as_before():
    """A screened QP (``screen=True``) refuses, without ProxQP (info None, x NaN), a problem after a failure whose rows
    the LP finds infeasible, and its solutions are the unscreened QP's to the last bit through a sequence that goes
    infeasible and back (the failing problem screened out is solved cold before the next one, which starts from
    it). The LP's verdict is the closed form: |x_i| <= 0.2 and E x = b hold together iff |b| <= 0.2 sum |E_row| (one
    equality row)."""
    size = 6
    hessian_root = RNG.normal(size=(size, size))
    hessian, gradient = hessian_root @ hessian_root.T + size * np.eye(size), RNG.normal(size=size)
    equality, inequality = RNG.normal(size=(1, size)), np.eye(size)
    lower, upper = np.full(size, -0.2), np.full(size, 0.2)
    reach = 0.2 * float(np.abs(equality).sum())  # the largest |E x| with |x_i| <= 0.2
    loads = [0.1, 0.3 * reach, 2.0 * reach, 3.0 * reach, 2.5 * reach, 0.2 * reach, 0.25 * reach]
    for load in (0.999 * reach, 1.001 * reach):
        assert feasible(equality, np.array([load]), inequality, lower, upper) == (load <= reach)
    screened, plain = WarmQP(), WarmQP()
    for k, load in enumerate(loads):
        rhs = np.array([load])
        x, solved, info = screened.solve(hessian, gradient, equality, rhs, inequality, lower, upper, screen=True)
        reference, reference_solved, _ = plain.solve(hessian, gradient, equality, rhs, inequality, lower, upper)
        assert solved == reference_solved == (load <= reach)
        if solved:
            np.testing.assert_array_equal(x, reference)
        elif k > 0 and loads[k - 1] > reach:  # after a failure: refused by the LP, ProxQP not run
            assert info is None and np.isnan(x).all()


def test_one_row_servo_solve_is_the_pseudo_inverses():
    """One prescribed row, three controls: the least-effort controls (the compiled least_norm) equal numpy's
    pseudo-inverse (1e-14 relative)."""
    nv = 3
    actuation = Actuation(np.eye(nv), ("a", "b", "c"), np.full(nv, -np.inf), np.full(nv, np.inf))
    solver = ServoSolver(np.array([True]), ("servo",), actuation)
    decoupling, demand = RNG.normal(size=(1, nv)), RNG.normal(size=1)
    controls = solver._controls(decoupling, demand, (0.0, np.zeros(nv), np.zeros(nv)))
    expected = np.linalg.pinv(decoupling, rcond=1e-12) @ demand
    assert np.abs(controls - expected).max() < 1e-14 * np.abs(expected).max()


def _exact_closest(matrix: np.ndarray, rhs: np.ndarray, target: np.ndarray) -> np.ndarray:
    """target + A^T (A A^T)^-1 (rhs - A target) for A of full row rank, in rational arithmetic, rounded once."""
    rows = [[Fraction(x) for x in row] for row in matrix.tolist()]
    start = [Fraction(x) for x in target.tolist()]
    k, m = len(rows), len(start)
    residual = [Fraction(rhs[i]) - sum(rows[i][j] * start[j] for j in range(m)) for i in range(k)]
    system = [[sum(rows[i][c] * rows[j][c] for c in range(m)) for j in range(k)] + [residual[i]] for i in range(k)]
    for c in range(k):  # Gauss-Jordan on the (exact) normal equations
        for r in range(k):
            if r != c:
                factor = system[r][c] / system[c][c]
                system[r] = [a - factor * b for a, b in zip(system[r], system[c], strict=True)]
    y = [system[i][k] / system[i][i] for i in range(k)]
    return np.array([float(start[j] + sum(rows[i][j] * y[i] for i in range(k))) for j in range(m)])


@pytest.mark.parametrize("condition", [1.0, 50.0, 1e3, 1e5, "deficient", "tall"])
def test_closest_solution_is_the_pseudo_inverses(condition):
    """closest_solution(A, b, x0) = x0 + A^+ (b - A x0): through Cholesky (well conditioned) or the SVD (ill
    conditioned, rank-deficient, more rows than columns). Of full row rank, against the exact value (rational
    arithmetic) to 1e-12 relative, or eps cond(A) where that is larger (a backward-stable SVD's forward error:
    measured 6.0e-12 at cond 1e5, numpy's pseudo-inverse 6.7e-12, the two 4.6e-12 apart); rank-deficient or tall,
    against numpy's pseudo-inverse (rcond 1e-10) to 1e-12."""
    left, _ = np.linalg.qr(RNG.normal(size=(6, 6)))
    right, _ = np.linalg.qr(RNG.normal(size=(12, 12)))
    singular = np.geomspace(1.0, 1.0 / condition, 6) if isinstance(condition, float) else np.geomspace(1.0, 0.1, 6)
    matrix = left @ np.diag(singular) @ right[:6]
    if condition == "deficient":
        matrix[-1] = matrix[0] + matrix[1]
    if condition == "tall":
        matrix = matrix[:, :4]
    rhs, target = RNG.normal(size=6), RNG.normal(size=matrix.shape[1])
    if isinstance(condition, float):
        expected, tolerance = _exact_closest(matrix, rhs, target), max(1e-12, np.finfo(float).eps * condition)
    else:
        expected, tolerance = target + np.linalg.pinv(matrix, rcond=1e-10) @ (rhs - matrix @ target), 1e-12
    assert np.abs(closest_solution(matrix, rhs, target) - expected).max() < tolerance * np.abs(expected).max()


def test_mass_matrix_is_crbas_mirrored(sphere):
    """Kinematics' M (one pass, mirrored through flat indices) equals Pinocchio's crba with its upper triangle
    mirrored (1e-14 relative) and is symmetric to the bit."""
    q, v = moved(sphere, 0.1)
    kin = Kinematics(sphere.model)
    kin.update(q, v)
    upper = np.triu(pin.crba(sphere.model, sphere.model.createData(), q))
    expected = upper + np.triu(upper, 1).T
    assert np.abs(kin.mass_matrix - expected).max() < 1e-14 * np.abs(expected).max()
    assert np.array_equal(kin.mass_matrix, kin.mass_matrix.T)
    assert np.array_equal(sphere.mass_matrix(q), expected)
