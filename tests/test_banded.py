"""The banded path against Pinocchio's own solve (the native path, its reference): accelerations,
multipliers, whole trajectories, the choice of path and the fallback at a singular configuration."""

from __future__ import annotations

import json
from fractions import Fraction

import numpy as np
import pinocchio as pin
import pytest

from pinstab import build_system, load_scene, simulate
from pinstab.cli import main
from pinstab.constraints import ConstraintSet, FrameClosure
from pinstab.errors import SolverError
from pinstab.integration.passages import Conditioning, tangent_turn
from pinstab.kinematics import Kinematics
from pinstab.paths import banded
from pinstab.paths.banded import BandedDynamics, BandedProjector
from pinstab.paths.native import NativeDynamics
from pinstab.projection import GeneralProjector

KP, KD = 100.0, 20.0  # [1/s^2], [1/s]


def _closures(scene) -> list[FrameClosure]:
    return [c for c in scene.constraints if isinstance(c, FrameClosure)]


def _aligned(model: pin.Model) -> np.ndarray:
    """The N-four-bar with every link along x: every loop singular at once."""
    q = np.zeros(model.nq)
    for joint in range(1, model.njoints):
        q[model.joints[joint].idx_q] = -np.pi / 2 if model.names[joint].startswith("crank") else np.pi / 2
    return q


def _world_closures(scene, q: np.ndarray) -> list[FrameClosure]:
    """The scene's closures with every other one pinned to the world at its point b's place at q."""
    model, data = scene.model, scene.model.createData()
    pin.framesForwardKinematics(model, data, q)
    closures = []
    for index, closure in enumerate(_closures(scene)):
        if index % 2:
            placement = pin.SE3(np.eye(3), data.oMf[closure.frame_b].translation.copy())
            closure = FrameClosure(closure.name, "planar-point", closure.frame_a, None, placement, "xy")
        closures.append(closure)
    return closures


@pytest.mark.parametrize("world", [False, True])
def test_banded_solve_equals_pinocchios_off_the_manifold(world):
    """At states off the constraint manifold (perturbed q, random v and joint torques) the banded LU
    gives Pinocchio's accelerations and multipliers, corrector included (to 1e-9 relative; measured
    ~1e-13), with closures between two bodies and to the world."""
    scene = load_scene("nfourbar", N=6)
    rng = np.random.default_rng(7)
    closures = _world_closures(scene, scene.q0) if world else _closures(scene)
    ours = BandedDynamics(scene.model, closures, KP, KD)
    reference = NativeDynamics(scene.model, closures, KP, KD, mu=1e-12)
    assert ours.band < ours.size / 4
    for _ in range(5):
        q = scene.q0 + 0.05 * rng.normal(size=scene.model.nq)
        v, tau = rng.normal(size=scene.model.nv), rng.normal(size=scene.model.nv)
        expected = reference.acceleration(q, v, tau).copy()
        got = ours.acceleration(q, v, tau)
        assert not ours.singular
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
        multipliers = reference.multipliers()
        np.testing.assert_allclose(ours.multipliers(), multipliers, rtol=0, atol=1e-9 * np.abs(multipliers).max())


def test_singular_and_redundant_rows_are_flagged():
    """All links aligned (every loop at its singular configuration) and 3-D point closures on a planar
    mechanism (an identically zero z row each) make the KKT matrix singular: the solve says so."""
    scene = load_scene("nfourbar", N=6)
    model, zero = scene.model, np.zeros(scene.model.nv)
    aligned = BandedDynamics(model, _closures(scene), KP, KD)
    aligned.acceleration(_aligned(model), zero, zero)
    assert aligned.singular
    aligned.acceleration(scene.q0, zero, zero)
    assert not aligned.singular
    points = [FrameClosure(c.name, "point", c.frame_a, c.frame_b) for c in _closures(scene)]
    redundant = BandedDynamics(model, points, KP, KD)
    redundant.acceleration(scene.q0, zero, zero)
    assert redundant.singular


def test_default_run_takes_the_banded_path_and_keeps_the_reference_trajectory(monkeypatch):
    """RK4 at 1 ms over 1 s of the N-four-bar, through its first singular passage (t = 0.72 s): the
    default run (banded path) and the run with Pinocchio's solve named (native path) stay within
    1e-10 rad (measured 4.9e-12: rounding amplified by the passage; the same runs agree to 1e-13
    before it), the stages nearest the passage are refined on the band (none handed to Pinocchio), and the JSON
    says which path ran and why."""
    monkeypatch.setattr(banded, "MIN_CLOSURES", 8)
    scene = load_scene("nfourbar", N=8)
    ours = simulate(scene, "baumgarte", "rk4", 1e-3, 1.0)
    reference = simulate(scene, "baumgarte", "rk4", 1e-3, 1.0, solver="pinocchio")
    assert ours.info.path == "banded" and reference.info.path == "native"
    assert "8 point closures" in ours.info.path_reason and "band of 6" in ours.info.path_reason
    before = ours.t < 0.7
    np.testing.assert_allclose(ours.q[before], reference.q[before], rtol=0, atol=1e-13)
    np.testing.assert_allclose(ours.q, reference.q, rtol=0, atol=1e-10)
    counts = ours.info.solver_statistics.status_counts
    assert counts["banded"] >= 4 * ours.steps and counts["banded refined"] > 0
    assert ours.info.solver_statistics.fallbacks == 0


def test_the_banded_path_starts_where_it_pays():
    """Pinocchio's solve below :data:`MIN_CLOSURES` closures, the banded one from there; naming the
    ``pinocchio`` solver, or a method with post-step corrections, keeps Pinocchio's."""
    few, many = load_scene("nfourbar", N=banded.MIN_CLOSURES - 1), load_scene("nfourbar", N=banded.MIN_CLOSURES)
    for scene, method, solver, path in [
        (few, "baumgarte", None, "native"),
        (many, "baumgarte", None, "banded"),
        (many, "baumgarte", "pinocchio", "native"),
        (many, "projection", None, "native"),
    ]:
        system = build_system(scene, method, solver)
        system.bind(1e-3, "rk4", scene.q0)
        assert system.path == path


def test_a_singular_stage_is_solved_by_pinocchio(monkeypatch):
    """At rest at the aligned configuration the banded path hands the evaluation to Pinocchio's solve
    (the native path's result: finite, equal to 1e-12) and counts a fallback."""
    monkeypatch.setattr(banded, "MIN_CLOSURES", 6)
    scene = load_scene("nfourbar", N=6)
    system = build_system(scene, "baumgarte", None, kp=KP, kd=KD)
    system.bind(1e-3, "rk4", scene.q0)
    assert system.path == "banded"
    reference = build_system(scene, "baumgarte", "pinocchio", kp=KP, kd=KD)
    reference.bind(1e-3, "rk4", scene.q0)
    q, v = _aligned(scene.model), np.zeros(scene.model.nv)
    got, expected = system.acceleration(q, v, 0.0, 0), reference.acceleration(q, v, 0.0, 0)
    assert np.isfinite(expected).all()
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    assert system.statistics.fallbacks == 1 and system.statistics.status_counts["banded"] == 0


def test_the_banded_conditioning_equals_the_svds():
    """sigma_r / sigma_1 of G from the banded eigensolver equals the dense SVD's (the passage watch's
    sample) to 1e-14, far from and near the singular configuration."""
    scene = load_scene("nfourbar", N=6)
    system = build_system(scene)
    ours = BandedDynamics(scene.model, _closures(scene), KP, KD)
    reference = Conditioning(system.model, scene.q0)
    aligned = _aligned(scene.model)
    for share in (0.0, 0.5, 0.9, 0.999, 0.9999):
        q = (1 - share) * scene.q0 + share * aligned
        expected = reference.relative(q, 0.0)
        assert ours.relative_singular_value(q, reference.rank) == pytest.approx(expected, rel=0, abs=1e-14)
    assert reference.relative(q, 0.0) < 1e-3


def test_run_json_names_the_banded_path(capsys):
    """``pinstab run --json`` says which path ran and why."""
    assert main(["run", "nfourbar", "--param", f"N={banded.MIN_CLOSURES}", "--duration", "0.005", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["path"] == "banded"
    assert f"{banded.MIN_CLOSURES} point closures" in result["path_reason"]


def _branched_model(spherical: pin.JointModel) -> tuple[pin.Model, list[FrameClosure]]:
    """A free-flying base with six branches (a ``spherical`` joint, a prismatic and a revolute joint on
    unaligned axes), each branch's tip pinned to the world where it is at the neutral configuration."""
    model = pin.Model()
    rng = np.random.default_rng(3)

    def body(joint: int) -> None:
        model.appendBodyToJoint(joint, pin.Inertia.Random(), pin.SE3.Identity())

    base = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "base")
    body(base)
    tips = []
    for branch in range(6):
        axis = rng.normal(size=3)
        parent = model.addJoint(base, spherical, pin.SE3(np.eye(3), rng.normal(size=3)), f"ball{branch}")
        body(parent)
        parent = model.addJoint(
            parent, pin.JointModelPrismaticUnaligned(axis / np.linalg.norm(axis)), pin.SE3.Random(), f"slide{branch}"
        )
        body(parent)
        parent = model.addJoint(
            parent,
            pin.JointModelRevoluteUnaligned(*(axis[::-1] / np.linalg.norm(axis))),
            pin.SE3.Random(),
            f"hinge{branch}",
        )
        body(parent)
        tips.append(model.addFrame(pin.Frame(f"tip{branch}", parent, pin.SE3.Random(), pin.FrameType.OP_FRAME)))
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    closures = [
        FrameClosure(f"pin{index}", "point", tip, None, pin.SE3(np.eye(3), data.oMf[tip].translation.copy()))
        for index, tip in enumerate(tips)
    ]
    return model, closures


@pytest.mark.parametrize("spherical", [pin.JointModelSpherical(), pin.JointModelSphericalZYX()], ids=["ball", "zyx"])
def test_banded_solve_equals_pinocchios_on_other_joints(spherical):
    """Free-flyer, spherical, unaligned prismatic and revolute joints: the banded kernel's nonlinear effects
    (its world-frame pass from the Jacobian; with ZYX spherical joints, whose motion subspace turns with q,
    Pinocchio's nonLinearEffects) give Pinocchio's accelerations to 1e-9 relative (measured ~1e-13)."""
    model, closures = _branched_model(spherical)
    assert model.check(model.createData())
    ours = BandedDynamics(model, closures, KP, KD)
    reference = NativeDynamics(model, closures, KP, KD, mu=1e-12)
    rng = np.random.default_rng(11)
    for _ in range(5):
        q = pin.integrate(model, pin.neutral(model), 0.1 * rng.normal(size=model.nv))
        v, tau = rng.normal(size=model.nv), rng.normal(size=model.nv)
        expected = reference.acceleration(q, v, tau).copy()
        got = ours.acceleration(q, v, tau)
        assert not ours.singular
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.abs(expected).max())


@pytest.mark.parametrize("world", [False, True])
def test_the_kernels_violation_equals_the_models(world):
    """The drift check's figures on the banded path (compiled: max |phi|, max |G v| over the rows) equal the
    model's own (pinstab's constraint rows in Python) to 1e-12 of their size, off the manifold, with closures
    between bodies and to the world."""
    scene = load_scene("nfourbar", N=6)
    closures = _world_closures(scene, scene.q0) if world else _closures(scene)
    rows, kin = ConstraintSet(closures, scene.model.nv), Kinematics(scene.model)
    ours = BandedDynamics(scene.model, closures, KP, KD)
    rng = np.random.default_rng(5)
    for _ in range(5):
        q, v = scene.q0 + 0.05 * rng.normal(size=scene.model.nq), rng.normal(size=scene.model.nv)
        kin.update(q, v)
        got, expected = ours.violation(q, v), rows.violation(rows.values(kin, q, v, 0.0, False))
        assert expected.position > 1e-3 and expected.velocity > 1e-2
        np.testing.assert_allclose(got, expected, rtol=1e-12)


def _exact_solution(matrix: np.ndarray, right: np.ndarray) -> np.ndarray:
    """The solution of matrix x = right with the entries taken as exact binary fractions, by Gaussian
    elimination in rational arithmetic (no rounding), rounded to doubles at the end."""
    n = len(right)
    rows = [[Fraction(float(x)) for x in row] + [Fraction(float(r))] for row, r in zip(matrix, right, strict=True)]
    for column in range(n):
        pivot = max(range(column, n), key=lambda i: abs(rows[i][column]))
        rows[column], rows[pivot] = rows[pivot], rows[column]
        for i in range(column + 1, n):
            if rows[i][column]:
                factor = rows[i][column] / rows[column][column]
                rows[i] = [x - factor * y for x, y in zip(rows[i], rows[column], strict=True)]
    solution = [Fraction(0)] * n
    for i in reversed(range(n)):
        known = sum(rows[i][j] * solution[j] for j in range(i + 1, n))
        solution[i] = (rows[i][n] - known) / rows[i][i]
    return np.array([float(x) for x in solution])


@pytest.mark.parametrize("closeness", [0.5, 0.05])
def test_a_near_singular_stage_is_refined_to_the_exact_kkt_solution(closeness):
    """Near the singular configuration (the state of a run at its first passage, t = 0.72 s, moved towards the
    aligned configuration by ``closeness``: the LU's pivot ratio 3.7e-7, 3.7e-9, below the 1e-6 that used to hand
    the stage to Pinocchio) the banded LU's solution is refined (residuals in extended precision) and used: its
    accelerations equal the exact rational solution of the KKT system formed independently (Pinocchio's crba and
    nonLinearEffects, pinstab's Python constraint rows) to 1e-9 of their size (the inputs' rounding times the
    conditioning bounds any solve there: Pinocchio's too)."""
    scene = load_scene("nfourbar", N=10)
    model, tau = scene.model, np.zeros(scene.model.nv)
    run = simulate(scene, "baumgarte", "rk4", 1e-3, 0.72)
    aligned = _aligned(model)
    q, v = aligned + closeness * (run.q[-1] - aligned), run.v[-1]
    closures = _closures(scene)
    ours = BandedDynamics(model, closures, KP, KD)
    got = ours.acceleration(q, v, tau)
    assert ours.kernel.pivot_ratio < banded.PIVOT_TOLERANCE and ours.kernel.refinements == 1 and not ours.singular
    rows, kin, data = ConstraintSet(closures, model.nv), Kinematics(model), pin.Data(model)
    kin.update(q, v)
    values = rows.values(kin, q, v, 0.0, True)
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    jacobian = values.jacobian
    right = np.concatenate(
        [tau - pin.nonLinearEffects(model, data, q, v), -values.drift - KP * values.phi - KD * jacobian @ v]
    )
    kkt = np.block([[mass, jacobian.T], [jacobian, np.zeros((len(jacobian), len(jacobian)))]])
    expected = _exact_solution(kkt, right)[: model.nv]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.abs(expected).max())


def test_the_kernel_computes_in_a_given_data():
    """The banded kernel computes in a Data it is given (the model's scratch on the banded path: no third pin 4.1
    Data of nv^3 tensors per run): the same accelerations to the bit as in its own, the Data's mass matrix written;
    a Data of another model or another object is refused by name."""
    scene = load_scene("nfourbar", N=6)
    model, closures = scene.model, _closures(scene)
    data = pin.Data(model)
    own, shared = BandedDynamics(model, closures, KP, KD), BandedDynamics(model, closures, KP, KD, data=data)
    v, tau = np.linspace(-1.0, 1.0, model.nv), np.zeros(model.nv)
    np.testing.assert_array_equal(shared.acceleration(scene.q0, v, tau), own.acceleration(scene.q0, v, tau))
    np.testing.assert_allclose(np.triu(data.M), np.triu(pin.crba(model, pin.Data(model), scene.q0)), atol=1e-14)
    with pytest.raises(SolverError, match="data: a pinocchio.Data of another model; give pin.Data"):
        BandedDynamics(model, closures, KP, KD, data=pin.Data(load_scene("fourbar").model))
    with pytest.raises(SolverError, match="data: not a pinocchio.Data; give pin.Data"):
        BandedDynamics(model, closures, KP, KD, data=model)
    system = build_system(scene, "baumgarte")
    system.bind(1e-3, "rk4", scene.q0)
    assert system.path == "banded"
    q = scene.q0 + 0.01
    system.acceleration(q, v, 0.0)
    np.testing.assert_allclose(
        np.triu(system.model.scratch.M), np.triu(pin.crba(model, pin.Data(model), q)), atol=1e-14
    )


def test_the_kernels_rows_and_projections_equal_the_general_ones():
    """N = 12 off the manifold (perturbed q, v): the kernel's phi, G and G v equal pinstab's Python rows to rounding
    (1e-14); the banded projector's position step and velocity projection equal the general projector's
    (least squares on the dense rows) to 1e-12 relative; the QR tangent spans the SVD's ker G (principal angle
    < 1e-10 rad)."""
    scene = load_scene("nfourbar", N=12)
    system = build_system(scene)
    system.bind(1e-3, "rk4", scene.q0)
    assert isinstance(system.projector, BandedProjector)
    model, solve = system.model, system.banded
    general = GeneralProjector(model)
    rng = np.random.default_rng(3)
    svd = Conditioning(model, scene.q0)
    compiled = Conditioning(model, scene.q0, solve.relative_singular_value, solve.jacobian)
    for _ in range(4):
        q = scene.q0 + 0.02 * rng.normal(size=model.nq)
        v = rng.normal(size=model.nv)
        values = model.constraint_values(q, v, 0.0)
        np.testing.assert_allclose(solve.residual(q), values.phi, rtol=0, atol=1e-14)
        np.testing.assert_allclose(solve.jacobian(q), values.jacobian, rtol=0, atol=1e-14)
        np.testing.assert_allclose(solve.rate(q, v), values.velocity_residual, rtol=0, atol=1e-13)
        step, worst = system.projector.position_step(q, 0.0)
        expected, expected_worst = general.position_step(q, 0.0)
        np.testing.assert_allclose(step, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
        assert worst == pytest.approx(expected_worst, rel=1e-14)
        projected = system.projector.velocity_projection(q, v, 0.0)
        np.testing.assert_allclose(projected, general.velocity_projection(q, v, 0.0), rtol=0, atol=1e-12)
        assert tangent_turn(compiled.tangent(q, 0.0), svd.tangent(q, 0.0)) < 1e-10


def test_the_banded_projector_falls_back_at_a_singular_configuration():
    """At the aligned configuration (every loop singular) the banded KKT solve refuses (None) and the projector
    gives the general projector's least-squares answer."""
    scene = load_scene("nfourbar", N=12)
    system = build_system(scene)
    system.bind(1e-3, "rk4", scene.q0)
    q = _aligned(scene.model) + 1e-3
    v = np.ones(scene.model.nv)
    assert system.banded.project(_aligned(scene.model), np.ones(system.banded.rows)) is None
    fallback = system.projector.fallback
    step, worst = system.projector.position_step(_aligned(scene.model), 0.0)
    expected, expected_worst = fallback.position_step(_aligned(scene.model), 0.0)
    np.testing.assert_array_equal(step, expected)
    assert worst == expected_worst
    assert np.isfinite(system.projector.velocity_projection(q, v, 0.0)).all()


def test_a_banded_run_builds_one_pinocchio_data(monkeypatch):
    """The assembly, the native solve's proximal choice and the compiled kernel compute in the model's scratch
    ``Data``; the kinematics' own (a long chain's is costly: four nv^3 tensors) is never built on the banded path,
    and is built once where Python's passes need it (the general path)."""
    import pinstab.kinematics
    import pinstab.model

    built = []
    for module in (pinstab.kinematics, pinstab.model):
        original = module.new_data
        monkeypatch.setattr(
            module,
            "new_data",
            lambda model, original=original, where=module.__name__: built.append(where) or original(model),
        )
    run = simulate(load_scene("nfourbar", N=10), dt=1e-3, duration=0.05)
    assert run.info.path == "banded" and built == ["pinstab.model"]
    simulate(load_scene("nfourbar", N=10), dt=1e-3, duration=0.05, solver="dense")
    assert built == ["pinstab.model", "pinstab.model", "pinstab.kinematics"]
