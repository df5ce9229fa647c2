"""The compiled step loop (``pinstab._compiled``, ``cpp/``) against the Python loop it takes the steps of: the same
trajectories to the last bit on the native and the banded paths for every scheme it takes, the same samples
with ``record_every``, the stop before an evaluation that is not to be used, and the runs it leaves to Python."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from conftest import with_python_force
from pinstab import build_system, load_scene, simulate
from pinstab.cli import main
from pinstab.constraints import FrameClosure
from pinstab.integration.compiled import SCHEMES, CompiledSteps, compiled_obstacle, kernel_obstacle, steps_before
from pinstab.integration.schemes import INTEGRATORS, Integrator
from pinstab.paths.banded import BandedDynamics


def _run_both(monkeypatch, scene, integrator, duration, **options):
    fast = simulate(scene, "baumgarte", integrator, 1e-3, duration, **options)
    with monkeypatch.context() as patch:
        patch.setattr(CompiledSteps, "of", classmethod(lambda cls, system, stepper: None))
        slow = simulate(scene, "baumgarte", integrator, 1e-3, duration, **options)
    return fast, slow


@pytest.mark.parametrize("integrator", [*SCHEMES, "dopri5", "dop853"])
def test_native_path_bitwise_equal_to_the_python_loop(monkeypatch, integrator):
    """The four-bar over 2 s (2000 steps), the fixed schemes and the tableaus' fixed steps: q, v and t equal to the
    last bit (the same Pinocchio call, the same sums in the same order), almost every step compiled (the first
    chunk's solves are checked in Python)."""
    fast, slow = _run_both(monkeypatch, load_scene("fourbar"), integrator, 2.0)
    assert fast.info.path == slow.info.path == "native"
    assert fast.info.compiled_steps >= 1900 and slow.info.compiled_steps == 0
    np.testing.assert_array_equal(fast.t, slow.t)
    np.testing.assert_array_equal(fast.q, slow.q)
    np.testing.assert_array_equal(fast.v, slow.v)
    assert fast.info.solver_statistics.solves == slow.info.solver_statistics.solves


@pytest.mark.parametrize(("scene", "options"), [("fourbar", {"solver": "proxsuite"}), ("cassie-legs", {})])
def test_python_evaluation_fixed_tableau_steps_bitwise_equal(monkeypatch, scene, options):
    """dop853's fixed steps over 0.2 s on the general path (the four-bar with proxsuite) and with force elements on
    the core path (cassie-legs' springs and dampers): the compiled loop on the system's Python evaluation or the core
    kernel takes the Python loop's steps to the last bit."""
    fast, slow = _run_both(monkeypatch, load_scene(scene), "dop853", 0.2, **options)
    assert fast.info.path == slow.info.path and slow.info.compiled_steps == 0
    np.testing.assert_array_equal(fast.q, slow.q)
    np.testing.assert_array_equal(fast.v, slow.v)
    assert fast.info.solver_statistics.solves == slow.info.solver_statistics.solves


def test_banded_path_bitwise_equal_to_the_python_loop(monkeypatch):
    """The N-four-bar, N = 30 (banded), RK4 over 0.5 s, one sample in 7 kept: equal to the last bit, the same
    samples (steps and times) and solve counts."""
    fast, slow = _run_both(monkeypatch, load_scene("nfourbar", N=30), "rk4", 0.5, record_every=7)
    assert fast.info.path == "banded" and fast.info.compiled_steps > 0
    np.testing.assert_array_equal(fast.t, slow.t)
    np.testing.assert_array_equal(fast.q, slow.q)
    np.testing.assert_array_equal(fast.v, slow.v)
    assert fast.info.solver_statistics.status_counts == slow.info.solver_statistics.status_counts


@pytest.mark.parametrize("integrator", list(SCHEMES))
@pytest.mark.filterwarnings("ignore::pinstab.errors.ZeroDynamicsWarning")  # the free shoulder whirls up
def test_servo_path_bitwise_equal_to_the_python_loop(monkeypatch, integrator):
    """double-pendulum-servo over 0.5 s (the servo path; its targets read at the stages' times): the compiled loop's
    states equal the Python loop's (the same kernel called per stage) to the last bit."""
    fast, slow = _run_both(monkeypatch, load_scene("double-pendulum-servo"), integrator, 0.5)
    assert fast.info.path == slow.info.path == "servo"
    assert fast.info.compiled_steps == 499 and slow.info.compiled_steps == 0
    np.testing.assert_array_equal(fast.q, slow.q)
    np.testing.assert_array_equal(fast.v, slow.v)
    assert fast.info.solver_statistics.status_counts == slow.info.solver_statistics.status_counts


def test_compiled_banded_path_matches_pinocchios_reference():
    """Independent check: the compiled banded run against Pinocchio's constraintDynamics (solver pinocchio,
    Python loop) on N = 24, RK4 over 1 s: crank angles to 1e-10 rad."""
    scene = load_scene("nfourbar", N=24)
    ours = simulate(scene, "baumgarte", "rk4", 1e-3, 1.0)
    reference = simulate(scene, "baumgarte", "rk4", 1e-3, 1.0, solver="pinocchio")
    assert ours.info.path == "banded" and reference.info.path == "native"
    assert np.abs(ours.q - reference.q).max() <= 1e-10


def test_a_singular_evaluation_stops_the_compiled_loop_before_its_step():
    """At the aligned configuration (every loop singular) the banded kernel refuses the first evaluation: the
    compiled loop does no step and says so; two steps from a regular state are done."""
    scene = load_scene("nfourbar", N=24)
    system = build_system(scene)
    system.bind(1e-3, "rk4", scene.q0)
    assert system.path == "banded"
    kernel = system.compiled_kernel()
    model = scene.model
    aligned = np.zeros(model.nq)
    for joint in range(1, model.njoints):
        aligned[model.joints[joint].idx_q] = -np.pi / 2 if model.names[joint].startswith("crank") else np.pi / 2
    tau = np.zeros(model.nv)
    assert kernel.run(SCHEMES["rk4"], aligned, np.zeros(model.nv), tau, 1e-3, 5)[2] == 0
    qs, vs, done = kernel.run(SCHEMES["rk4"], scene.q0, scene.v0, tau, 1e-3, 2)
    assert done == 2 and np.isfinite(qs).all()


@pytest.mark.parametrize("scene", ["stiff-fourbar", "slider-crank", "cassie-legs"])
def test_native_path_with_force_elements_bitwise_equal_to_the_python_loop(monkeypatch, scene):
    """The native path's scenes with force elements (a spring-damper on an open chain; a joint torque and a damper to a
    world point on a closed one; joint springs and dampers on cassie-legs' closures) over 0.1 s of RK4 at the scene's
    step: the native kernel takes every element (cpp/force_elements.cpp, the sums in Python's order), so the compiled
    loop steps with it, and q, v equal the Python loop's (Python's elements, Pinocchio's solve) to the last bit."""
    loaded = load_scene(scene)
    dt = loaded.step or 1e-3
    fast = simulate(loaded, "baumgarte", "rk4", dt, 0.1)
    with monkeypatch.context() as patch:
        patch.setattr(CompiledSteps, "of", classmethod(lambda cls, system, stepper: None))
        slow = simulate(loaded, "baumgarte", "rk4", dt, 0.1)
    assert fast.info.path == slow.info.path == "native"
    assert fast.info.compiled_steps >= 0.8 * 0.1 / dt and slow.info.compiled_steps == 0
    np.testing.assert_array_equal(fast.q, slow.q)
    np.testing.assert_array_equal(fast.v, slow.v)


def test_runs_left_to_python_say_why():
    """A registered integrator of its own step and a correcting method keep the Python loop, each named (a tableau,
    dop853, does not); the general path and a force element without a compiled form on the native path (a user's,
    added to the slider-crank) run the compiled loop on the system's Python evaluation, kernel_obstacle naming why."""

    class OwnStep(Integrator):
        name = "own-step"

    scene = load_scene("fourbar")
    system = build_system(scene, "baumgarte")
    system.bind(1e-3, "dop853", scene.q0)
    assert "own-step is neither one of" in compiled_obstacle(system, OwnStep(system))
    assert compiled_obstacle(system, INTEGRATORS.build("dop853", system)) is None
    for scene_name, options, reason in [
        ("fourbar", dict(solver="proxsuite"), "general path"),
        ("slider-crank", {}, "force element 'user' has no compiled form (the native kernel takes joint-spring"),
    ]:
        other = with_python_force(load_scene(scene_name))
        system = build_system(other, "baumgarte", **options)
        system.bind(1e-3, "rk4", other.q0)
        assert compiled_obstacle(system, INTEGRATORS.build("rk4", system)) is None
        assert reason in kernel_obstacle(system)
    system = build_system(scene, "projection")
    system.bind(1e-3, "rk4", scene.q0)
    assert "corrects" in compiled_obstacle(system, INTEGRATORS.build("rk4", system))


@pytest.mark.parametrize(
    ("k", "stop", "due", "expected"), [(0, 100, np.inf, 100), (0, 100, 0.0105, 11), (5, 8, 1.0, 3), (5, 100, 0.005, 0)]
)
def test_steps_before_the_watchs_next_sample(k, stop, due, expected):
    """The steps from k whose start time j dt lies before the due time (dt = 1 ms), capped at stop."""
    assert steps_before(k, stop, 1e-3, due) == expected
    taken = [j for j in range(k, stop) if j * 1e-3 < due]
    assert expected == len(taken)


def test_run_json_counts_the_compiled_steps(capsys):
    """``pinstab run --json`` of the four-bar says how many of its steps the compiled loop took: all but the last
    (shortened when dt does not divide the duration, it is always Python's), measured 999 of 1000."""
    assert main(["run", "fourbar", "--duration", "1", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["path"] == "native" and 890 <= result["compiled_steps"] <= 999


def test_conditioning_with_redundant_rows_equals_the_svds():
    """3-D point closures on the planar N-four-bar (N = 8): each adds an identically zero z row, so G has 24 rows
    of rank 16. The compiled sigma_16 / sigma_1 (an interior eigenvalue of the Gram matrix, found past the eight
    zero ones) equals the dense SVD's to 1e-13 along a path towards the aligned configuration."""
    scene = load_scene("nfourbar", N=8)
    model = scene.model
    points = [FrameClosure(c.name, "point", c.frame_a, c.frame_b) for c in scene.constraints]
    banded = BandedDynamics(model, points, 0.0, 0.0)
    aligned = np.zeros(model.nq)
    for joint in range(1, model.njoints):
        aligned[model.joints[joint].idx_q] = -np.pi / 2 if model.names[joint].startswith("crank") else np.pi / 2
    data = model.createData()
    for share in (0.0, 0.3, 0.9, 0.99, 0.999):
        q = (1 - share) * scene.q0 + share * aligned
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        rows = []
        for closure in points:  # G of point a - point b, world axes
            jacobians = []
            for frame in (closure.frame_a, closure.frame_b):
                jacobians.append(pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[:3])
            rows.append(jacobians[0] - jacobians[1])
        singular = np.linalg.svd(np.vstack(rows), compute_uv=False)
        assert int(np.sum(singular > 1e-9 * singular[0])) == 16
        assert banded.relative_singular_value(q, 16) == pytest.approx(singular[15] / singular[0], rel=0, abs=1e-13)
