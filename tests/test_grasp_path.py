"""Grasps on the core path (pinstab.paths.core, cpp/core_kernel.cpp, cpp/grasp_forces.cpp): sticking fingertip contacts
of every contact model, hold torques and constant wrenches evaluated compiled, against the general path's Python
evaluation and its direct KKT solve."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pinstab import load_scene, simulate
from pinstab.errors import GraspLostError
from pinstab.scene import scene_from_dict
from pinstab.simulate.loop import start_state
from pinstab.system import build_system

ROBOTS = Path(__file__).parents[1] / "robots"


def sphere_scene(**changes):
    """allegro-sphere with its push force and contacts' mu replaced (``push`` [N] along y, ``mu`` [-]), the hold's
    normal forces capped (``cap`` [N]), or with a joint torque ramping on the index finger's base joint (``torque``
    [N m] at 1 s)."""
    data = tomllib.loads((ROBOTS / "allegro-sphere.toml").read_text())
    if "push" in changes:
        data["forces"][1]["force"] = [0.0, changes["push"], 0.0]
    if "mu" in changes:
        for contact in data["contacts"]:
            contact["mu"] = changes["mu"]
    if "cap" in changes:
        data["forces"][0]["max_squeeze"] = changes["cap"]
    if "torque" in changes:
        ramp = [[0.0, 0.0], [1.0, changes["torque"]]]
        data["forces"].append({"name": "nudge", "kind": "joint-torque", "joint": "joint_1.0", "table": ramp})
    return scene_from_dict(data, name="allegro-sphere-variant", base_dir=ROBOTS)


def bound(scene, **options):
    system = build_system(scene, **options)
    q, v = start_state(scene, None, None)
    system.bind(1e-3, "rk4", q)
    return system, q, v


@pytest.mark.parametrize("name", ["allegro-sphere", "trifinger-cube", "nudged"])
def test_grasp_evaluation_equals_the_general_path(name):
    """At the start and at 8 states moved from it (configuration by 1e-3, velocities of 1e-2 per coordinate), at
    t = 0.1 s, the compiled evaluation's accelerations equal the general path's (pinstab's kinematics, the hold's least
    squares, proxsuite's direct solve) to 1e-11 of their largest, and its contact forces to 1e-12 N; "nudged" adds
    a joint torque table (the kernel's, cpp/core_kernel.cpp add_joint_torques)."""
    scene = sphere_scene(torque=0.02) if name == "nudged" else load_scene(name)
    system, q0, v0 = bound(scene)
    assert system.path == "core", system.path_reason
    model = system.model
    rng = np.random.default_rng(7)
    for k in range(9):
        q = pin.integrate(model.model, q0, 1e-3 * rng.standard_normal(model.nv) if k else np.zeros(model.nv))
        v = 1e-2 * rng.standard_normal(model.nv) if k else v0
        compiled = system.acceleration(q, v, 0.1, 0)
        assert not system.compiled_path.unusable
        general = system.dynamics(q, v, 0.1)
        scale = float(np.max(np.abs(general.acceleration)))
        np.testing.assert_allclose(compiled, general.acceleration, rtol=0, atol=1e-11 * scale)
        np.testing.assert_allclose(system.compiled_path.kernel.multipliers(), general.multipliers, rtol=0, atol=1e-12)
    assert system.statistics.status_counts["core cholesky"] == 9


def test_grasp_run_equals_the_general_run():
    """allegro-sphere over 0.5 s with RK4 at 1 ms: the core path's trajectory equals that of the general path (solver
    ``proxsuite`` named) to 1e-12 (rad, m; the ball moves by millimetres), every solve compiled, each solve's relative
    residual |G a - rhs| at rounding on both paths."""
    scene = load_scene("allegro-sphere")
    fast = simulate(scene, duration=0.5)
    general = simulate(scene, duration=0.5, solver="proxsuite")
    assert (fast.info.path, general.info.path) == ("core", "general")
    assert fast.info.solver_statistics.status_counts == {"core cholesky": 2000}
    # the kernel's |G a - rhs| (relative) is measured as the general path's is: rounding on both
    assert fast.info.solver_statistics.worst_primal_residual <= 1e-15
    assert general.info.solver_statistics.worst_primal_residual <= 1e-15
    np.testing.assert_allclose(fast.q, general.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.v, general.v, rtol=0, atol=1e-10)


def test_hold_forces_outside_their_cones_go_to_the_general_path():
    """With mu = 0.2 the hold's least-squares forces leave the cones (0.3 keeps them inside; the general path
    takes its QP, whose forces hold): the compiled evaluation is not used, the general path's acceleration is
    returned (to the QP's tolerance) and the evaluation counts as a fallback."""
    system, q, v = bound(sphere_scene(mu=0.2))
    assert system.path == "core"
    acceleration = system.acceleration(q, v, 0.0, 0)
    assert system.compiled_path.unusable
    general = system.dynamics(q, v, 0.0).acceleration  # its QP warm-started now: the same to its tolerance
    np.testing.assert_allclose(acceleration, general, rtol=0, atol=1e-6 * np.max(np.abs(general)))
    assert system.statistics.fallbacks == 1
    assert system.statistics.status_counts.get("core cholesky", 0) == 0
    assert system.statistics.status_counts["core hold outside its cones"] == 1


@pytest.mark.parametrize(("cap", "used"), [(3.0, True), (2.2, False)])
def test_a_capped_hold_is_compiled_while_its_forces_keep_the_cap(cap, used):
    """The hold's least-squares normal forces at the start are 1.87, 1.54, 1.76 and 2.51 N: under a cap of 3 N the
    compiled evaluation is used (and equals the general path's to 1e-11 of the largest acceleration); under 2.2 N the
    thumb's force exceeds it and the general path's capped solve is taken."""
    system, q, v = bound(sphere_scene(cap=cap))
    acceleration = system.acceleration(q, v, 0.0, 0)
    assert system.compiled_path.unusable is not used
    general = system.dynamics(q, v, 0.0).acceleration
    tolerance = 1e-11 if used else 1e-6  # the capped solve is a warm-started QP: the same to its tolerance
    np.testing.assert_allclose(acceleration, general, rtol=0, atol=tolerance * np.max(np.abs(general)))


def test_a_lost_grasp_is_named_as_on_the_general_path():
    """A 3 N push slides the ball: the core path stops the run with the general path's GraspLostError, at the same
    time (to 1e-12 s) and naming the same contacts."""
    scene = sphere_scene(push=3.0)
    errors = []
    for solver in (None, "proxsuite"):
        with pytest.raises(GraspLostError) as caught:
            simulate(scene, duration=0.5, solver=solver)
        errors.append(caught.value)
    assert errors[0].time == pytest.approx(errors[1].time, abs=1e-12)
    assert errors[0].contacts == errors[1].contacts
    assert str(errors[0]) == str(errors[1])


@pytest.mark.parametrize(
    ("scene", "options", "path", "reason"),
    [
        ("allegro-lift", {}, "core", "force(s) lift evaluated in Python"),
        ("allegro-box", {}, "core", "3 constraint block(s) of 12 rows"),
        ("allegro-tilt", {}, "core", "4 constraint block(s) of 12 rows"),
        (
            "allegro-sphere",
            {"solver_options": {"direct": False}},
            "general",
            "solver proxsuite solves every evaluation",
        ),
        ("allegro-sphere", {"method": "projection"}, "core", "4 constraint block(s)"),
        ("allegro-sphere", {"method": "mukharlyamov"}, "core", "4 constraint block(s)"),
        ("allegro-sphere", {"method": "mukharlyamov", "variant": "inertial"}, "core", "4 constraint block(s)"),
    ],
)
def test_the_core_path_is_taken_where_it_repeats_the_general_one(scene, options, path, reason):
    """The core path for an object-level controller (evaluated in Python, named), soft fingers' rotation rows and a
    tilting gravity, under a projection method (its corrections run in Python on any path) and Mukharlyamov's kinematic
    term (held over the stages) and its inertial one; the general path, with the reason named, where ProxQP is asked for
    every solve."""
    system, _, _ = bound(load_scene(scene), **options)
    assert system.path == path
    assert reason in system.path_reason
