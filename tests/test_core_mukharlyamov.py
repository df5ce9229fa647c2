"""Mukharlyamov's extended system (kinematic variant) on the core path (``cpp/core_kernel.cpp``: the term
-K (G v + g_t) - S phi per row, held over a step's stages with heun and rk4): the same runs as the general path's
(pinstab's Python rows and term, ProxQP's direct solve), the same drift, the held term at a stage > 0 of a step whose
evaluation the general path solves, and the kernel's held term against the stabilizer's."""

from __future__ import annotations

import numpy as np
import pytest

from pinstab import build_system, load_scene, simulate
from pinstab.paths.core import CoreDynamics
from pinstab.system import ConstrainedSystem

# (scene, duration [s]): scenes whose default runs take the core, with holonomic rows (delta, the dual Panda and its
# carried box, the trifinger's grasp) and nonholonomic ones (the rolling disk's rolling rows)
SCENES = [("delta", 0.1), ("dual-panda-box", 0.5), ("trifinger-cube", 0.5), ("rolling-disk", 1.0)]
# (integrator, options): the held term (rk4, heun: the default) and one evaluated at every stage (euler; rk4 --no-hold)
SCHEMES = [("rk4", {}), ("heun", {}), ("euler", {}), ("rk4", {"hold": False})]


def _runs(scene_name: str, duration: float, integrator: str, **options):
    """The run on the core and the same run on the general path (ProxQP named: the core is not taken)."""
    scene = load_scene(scene_name)
    core = simulate(scene, "mukharlyamov", integrator, duration=duration, progress=False, **options)
    general = simulate(
        scene, "mukharlyamov", integrator, duration=duration, progress=False, solver="proxsuite", **options
    )
    assert core.info.path == "core" and general.info.path == "general"
    assert len(core.t) == len(general.t)
    return core, general


@pytest.mark.filterwarnings("ignore::pinstab.errors.PenetrationWarning")
@pytest.mark.parametrize(("integrator", "options"), SCHEMES)
@pytest.mark.parametrize(("scene_name", "duration"), SCENES)
def test_the_core_repeats_the_general_path(scene_name, duration, integrator, options):
    """Automatic (dead-beat) gains: q equal to 1e-13 (measured <= 4.0e-15 over these runs), v to 1e-11 (measured <=
    3.8e-12, dual-panda-box with rk4 --no-hold; the rolling disk: 0). Not closer in v: the gains S ~ 1/dt^2 (1e6 1/s^2
    at dt = 1e-3) turn the rounding of phi, which the core's rows and pinstab's Python ones compute apart (1e-16 m),
    into 1e-10 m/s^2; with Baumgarte-sized gains the same runs agree to 5e-14 (the next test). The drift figures are
    the same: the largest position and velocity drift to 1e-3 relative (or 1e-13 absolute, where both are rounding)."""
    core, general = _runs(scene_name, duration, integrator, **options)
    assert np.max(np.abs(core.q - general.q)) <= 1e-13
    assert np.max(np.abs(core.v - general.v)) <= 1e-11
    for drift in ("position_drift", "velocity_drift"):
        assert np.isclose(np.max(getattr(core, drift)), np.max(getattr(general, drift)), rtol=1e-3, atol=1e-13)


@pytest.mark.filterwarnings("ignore::pinstab.errors.PenetrationWarning")
@pytest.mark.parametrize(("scene_name", "duration"), SCENES[:3])
def test_the_held_term_with_given_gains_repeats_the_general_path_to_rounding(scene_name, duration):
    """Given gains S = 100 1/s^2, K = 20 1/s, held over rk4's stages: q equal to 1e-14, v to 5e-14 (measured <=
    6.7e-16 in q, 1.6e-14 in v, trifinger-cube; delta 8.9e-16 in v)."""
    core, general = _runs(scene_name, duration, "rk4", kp=100.0, kd=20.0)
    assert np.max(np.abs(core.q - general.q)) <= 1e-14
    assert np.max(np.abs(core.v - general.v)) <= 5e-14


@pytest.mark.filterwarnings("ignore::pinstab.errors.SolverLimitWarning")
def test_cassie_on_the_core_keeps_the_drift_of_the_exact_solve():
    """The full Cassie (redundant loop rows, near-singular shin-spring triangles), 0.02 s: on the core, and its drift
    that of the general path with the KKT system solved whole in extended precision (``extended``): the largest
    position drift 2.956e-15 on both, velocity drift 1.388e-12 on both (to 1e-3 relative). The motions agree to 1e-8
    in q (measured 3.0e-9; v 1.2e-6): the core's pseudo-inverse cuts the triangles' near-singular direction that the
    extended solve keeps, as it does with Baumgarte's gains (benchmarks/results/core_equality.json: 1.2e-9 in q over
    0.2 s), and the dead-beat gains act on it harder."""
    scene = load_scene("cassie")
    core = simulate(scene, "mukharlyamov", "rk4", duration=0.02, progress=False)
    exact = simulate(scene, "mukharlyamov", "rk4", duration=0.02, progress=False, solver="extended")
    assert core.info.path == "core" and core.info.solver_statistics.fallbacks == 0
    assert np.max(np.abs(core.q - exact.q)) <= 1e-8
    for drift in ("position_drift", "velocity_drift"):
        assert np.isclose(np.max(getattr(core, drift)), np.max(getattr(exact, drift)), rtol=1e-3)


def test_a_fallback_at_a_later_stage_takes_the_term_the_kernel_held(monkeypatch):
    """Delta, rk4, 0.1 s on the Python step loop, with evaluations forced unusable (so the general path solves them):
    stage 2 of every 7th step (from step 3) and stage 0 of every 11th (from step 1). At a stage > 0 the general path
    must take the term the kernel held at the step's stage 0: the run equals the all-Python run to 1e-14 in q and
    5e-12 in v (measured 6.5e-16, 1.4e-12); the stabilizer's own stale term (from its last stage-0 fallback) leaves
    4.9e-14 and 9.8e-11."""
    scene = load_scene("delta")
    dt = scene.step or 1e-3
    monkeypatch.setattr(ConstrainedSystem, "compiled_kernel", lambda self: None)  # every stage through Python
    forced = []
    acceleration = CoreDynamics.acceleration

    def sometimes_unusable(self, q, v, tau, t, stage=0):
        result = acceleration(self, q, v, tau, t, stage)
        step = int(np.floor(t / dt + 1e-9))
        if (stage == 2 and step % 7 == 3) or (stage == 0 and step % 11 == 1):
            self.unusable = True
            forced.append((step, stage))
        return result

    monkeypatch.setattr(CoreDynamics, "acceleration", sometimes_unusable)
    core, general = _runs("delta", 0.1, "rk4")
    assert core.info.solver_statistics.fallbacks == len(forced) and {stage for _, stage in forced} == {0, 2}
    assert np.max(np.abs(core.q - general.q)) <= 1e-14
    assert np.max(np.abs(core.v - general.v)) <= 5e-12


def test_the_kernel_holds_its_stage_0_term():
    """The kernel's held term equals the stabilizer's at the same state (to 1e-9 of its largest entry: the S ~ 1e6
    1/s^2 times the rows' rounding); at stage 1 from another state the kernel's accelerations equal the general path's
    holding that term (to 1e-9 relative) and differ from a fresh evaluation's there; before a stage 0 there is no held
    term, and a stage > 0 is not used ("no held term")."""
    scene = load_scene("delta")
    system = build_system(scene, "mukharlyamov")
    system.bind(1e-3, "rk4", scene.q0)
    assert system.path == "core"
    path, model = system.compiled_path, system.model
    rng = np.random.default_rng(3)
    q0, v0 = scene.q0, 0.1 * rng.standard_normal(model.nv)
    q1, v1 = model.integrate(q0, 1e-3 * v0), v0 + 0.01 * rng.standard_normal(model.nv)
    tau = model.applied_force_at(q0, v0, 0.0)
    path.acceleration(q1, v1, tau, 0.0, 1)
    assert path.unusable and path.held_term() is None
    assert path.status_counts()["core no held term"] == 1

    path.acceleration(q0, v0, tau, 0.0, 0)
    held = path.held_term()
    system.dynamics(q0, v0, 0.0, 0)  # the stabilizer's own stage-0 term
    python_term = system.stabilizer._held_term
    assert np.max(np.abs(held - python_term)) <= 1e-9 * np.max(np.abs(python_term))

    tau1 = model.applied_force_at(q1, v1, 5e-4)
    on_core = path.acceleration(q1, v1, tau1, 5e-4, 1)
    assert not path.unusable
    system.stabilizer.hold_term(held)
    general = system.dynamics(q1, v1, 5e-4, 1).acceleration
    assert np.max(np.abs(on_core - general)) <= 1e-9 * np.max(np.abs(general))
    fresh = path.acceleration(q1, v1, tau1, 5e-4, 0)
    assert np.max(np.abs(fresh - on_core)) > 1e-3 * np.max(np.abs(general))
