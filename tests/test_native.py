"""The native path, sampled recording and the stepping loop's checks, each against a second method:
the general path, an every-step run, or a loop that checks every step."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import ROBOTS
from pinstab import DivergenceError, PinstabError, build_system, load_scene, simulate
from pinstab.analysis.fourbar import fourbar_motion
from pinstab.cli import main
from pinstab.integration import stepping
from pinstab.model import ConstrainedModel
from pinstab.paths.native import NativeDynamics


@pytest.mark.parametrize("method", ["projection", "post"])
@pytest.mark.parametrize("integrator", ["semi-implicit-euler", "rk4"])
def test_native_corrections_equal_the_general_ones(method, integrator):
    """Projection and post-stabilization with Pinocchio's algorithms move the four-bar as pinstab's
    own rows and ProxQP do: within 1e-9 rad over 1 s, and on the manifold (projection to its
    tolerance, post to the O(dt^2) error one correction leaves with semi-implicit Euler)."""
    native = simulate("fourbar", method, integrator, 2e-3, 1.0)
    general = simulate("fourbar", method, integrator, 2e-3, 1.0, solver="proxsuite")
    assert native.info.path == "native" and general.info.path == "general"
    np.testing.assert_allclose(native.q, general.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(native.v, general.v, rtol=0, atol=1e-8)
    assert native.position_drift.max() < (1e-12 if method == "projection" else 1e-7)
    assert native.info.correction_iterations_total > 0


def test_lazy_multipliers_equal_a_dense_solve_at_the_samples():
    """Multipliers computed after the run from the kept samples (native path) equal the dense
    backend's at the same states, same gains (to 1e-7 relative)."""
    scene = load_scene("slider-crank")
    trajectory = simulate(scene, "baumgarte", "rk4", 1e-3, 0.3, record_every=50)
    assert trajectory.info.path == "native"
    dense = build_system(scene, "baumgarte", "dense")
    for t, q, v, got in zip(trajectory.t, trajectory.q, trajectory.v, trajectory.multipliers, strict=True):
        expected = dense.dynamics(q, v, t).multipliers
        np.testing.assert_allclose(got, expected, atol=1e-7 * max(1.0, np.abs(expected).max()))


def test_record_every_keeps_the_every_step_samples():
    """Keeping every 7th step (and the last) gives exactly the every-step run's states there."""
    every_step = simulate("fourbar", dt=1e-3, duration=0.1)
    sampled = simulate("fourbar", dt=1e-3, duration=0.1, record_every=7)
    steps = [*range(0, 100, 7), 100]
    np.testing.assert_array_equal(sampled.t, every_step.t[steps])
    np.testing.assert_array_equal(sampled.q, every_step.q[steps])
    np.testing.assert_array_equal(sampled.position_drift, every_step.position_drift[steps])
    assert sampled.steps == every_step.steps == 100 and sampled.info.record_every == 7


def test_record_every_is_checked(capsys):
    with pytest.raises(PinstabError, match="record_every"):
        simulate("fourbar", dt=1e-3, duration=0.1, record_every=0)
    assert main(["run", "fourbar", "--record-every", "0", "--duration", "0.01"]) == 2
    assert "record_every" in capsys.readouterr().err


def test_a_divergence_is_located_at_the_step_a_per_step_check_finds(monkeypatch):
    """Checks every 100 steps plus a replay report the same step, time and last state as checking
    after every step."""
    # undamped and too stiff for the step: it diverges at step 224, inside the third chunk of checks
    arguments = dict(method="baumgarte", integrator="semi-implicit-euler", dt=1e-2, duration=5.0, kp=3.6e4, kd=0.0)
    with pytest.warns(Warning), pytest.raises(DivergenceError) as chunked:
        simulate("fourbar", **arguments)
    monkeypatch.setattr(stepping, "CHECK_STEPS", 1)
    with pytest.warns(Warning), pytest.raises(DivergenceError) as per_step:
        simulate("fourbar", **arguments)
    assert str(chunked.value) == str(per_step.value) and "(step 224)" in str(chunked.value)
    assert chunked.value.time == per_step.value.time
    np.testing.assert_array_equal(chunked.value.q, per_step.value.q)
    np.testing.assert_array_equal(chunked.value.trajectory.t, per_step.value.trajectory.t)


def test_dop853_has_order_eight():
    """Halving the step divides the four-bar's error against its independent model by about 2^8
    (measured 440 from 8 ms to 4 ms over 10 s; here 1 s)."""
    scene = load_scene("fourbar")
    errors = []
    for dt in (8e-3, 4e-3):
        run = simulate(scene, "projection", "dop853", dt, 1.0)
        errors.append(np.abs(run.q - fourbar_motion(scene, run.q[0], run.v[0], run.t).q).max())
    assert errors[0] / errors[1] > 2**7


def test_a_tilting_gravity_keeps_pinocchios_solve_off(tmp_path):
    """Pinocchio's solve takes the model's one gravity: a four-bar under a tilting gravity ([tilt]) runs on the core
    path (whose kernel tilts it, and whose trajectory is the general path's to 1e-12 rad), and moves otherwise than the
    untilted one (the crank's angle differs by more than 1e-3 rad after 1 s at 20 deg/s)."""
    text = (ROBOTS / "fourbar.toml").read_text().replace('"urdf/fourbar.urdf"', f'"{ROBOTS / "urdf/fourbar.urdf"}"')
    scene_file = tmp_path / "fourbar-tilt.toml"
    scene_file.write_text(text + '\n[tilt]\naxis = [1, 0, 0]\nrate = "20 deg/s"\n')
    tilted = simulate(load_scene(scene_file), duration=1.0)
    general = simulate(load_scene(scene_file), duration=1.0, solver="proxsuite")
    plain = simulate(load_scene("fourbar"), duration=1.0)
    assert (tilted.info.path, general.info.path, plain.info.path) == ("core", "general", "native")
    assert tilted.info.compiled_steps > 0  # the compiled loop takes its steps, the tilt in the kernel
    assert np.abs(tilted.q - general.q).max() <= 1e-12
    assert np.abs(tilted.q[-1] - plain.q[-1]).max() > 1e-3


@pytest.mark.parametrize("scene_name", ["fourbar", "slider-crank"])
def test_native_residual_is_the_relative_miss_of_pinstabs_rows(scene_name):
    """NativeDynamics.residual (the compiled rule the native kernel applies too) after a solve, for the solution and a
    perturbed acceleration, equals the primal residual without the free force's scale, |G a - rhs| / (|rhs| +
    |G|_F |a|), from pinstab's own rows (G, phi, gamma0 at (q, v), rhs = -gamma0 - Kp phi - Kd G v) to 1e-9 relative;
    0 for no closures."""
    scene = load_scene(scene_name)
    model = ConstrainedModel(scene)
    kp, kd = 100.0, 20.0
    native = NativeDynamics(scene.model, scene.constraints, kp, kd)
    rng = np.random.default_rng(35)
    q = scene.q0 + 0.05 * rng.normal(size=model.nv)
    v = rng.normal(size=model.nv)
    solved = native.acceleration(q, v, np.zeros(model.nv))
    model.kin.update(q, v)
    values = model.constraints.values(model.kin, q, v, 0.0, with_drift=True)
    rhs = -values.drift - kp * values.phi - kd * values.jacobian @ v
    for a in (solved, solved + 1e-3 * rng.normal(size=model.nv)):
        native.acceleration(q, v, np.zeros(model.nv))  # the residual reads the last solve's data
        scale = np.linalg.norm(rhs) + np.linalg.norm(values.jacobian) * np.linalg.norm(a)
        expected = np.linalg.norm(values.jacobian @ a - rhs) / scale
        assert abs(native.residual(v, a) - expected) <= 1e-9 * max(expected, 1e-6)
    assert NativeDynamics(scene.model, []).residual(v, solved) == 0.0
