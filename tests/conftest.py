"""Shared helpers for the test suite."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

DATA = Path(__file__).parent / "data"
ROBOTS = Path(__file__).resolve().parents[1] / "robots"


@pytest.fixture
def data_dir() -> Path:
    return DATA


def interruptible() -> None:
    """``preexec_fn`` of a child a test sends SIGINT: SIGINT at its default, as in a terminal's foreground job (a
    shell started in the background without job control hands its children SIGINT ignored, and Python keeps it so)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def random_configuration(model: pin.Model, rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    """A configuration a random tangent step away from neutral (valid on every joint group)."""
    return pin.integrate(model, pin.neutral(model), scale * rng.standard_normal(model.nv))


FOURBAR_LOOP = {
    "name": "loop",
    "kind": "planar-point",
    "plane": "xy",
    "frame_a": "coupler",
    "offset_a": [0.6, 0, 0],
    "frame_b": "rocker",
    "offset_b": [0.5, 0, 0],
}


def fourbar_dict(**changes) -> dict:
    """Scene-file content of the bundled four-bar (closure named ``loop``), with top-level keys replaced."""
    data = {
        "robot": {"urdf": str(ROBOTS / "urdf" / "fourbar.urdf")},
        "gravity": [0.0, -9.81, 0.0],
        "closures": [dict(FOURBAR_LOOP)],
        "initial": {"q": {"crank": 1.0, "coupler": -0.9, "rocker": 1.6}, "v": {"crank": 3.0}},
    }
    data.update(changes)
    return data


def coupler_spring(stiffness: float, damping: float = 0.0, rest_length: float = 0.3, anchor=(0.2, 0.6, 0.0)) -> dict:
    """A spring-damper from the four-bar coupler's midpoint to a world point."""
    return {
        "name": "spring",
        "kind": "spring-damper",
        "frame_a": "coupler",
        "offset_a": [0.3, 0.0, 0.0],
        "offset_b": list(anchor),
        "stiffness": stiffness,
        "damping": damping,
        "rest_length": rest_length,
    }


def pendulum_scene(length: float, gravity: float, initial: dict | None = None):
    """The point mass of tests/data/point_mass.urdf on a rod: phi = x^2 + y^2 - l^2 (a user constraint)."""
    from pinstab import HolonomicConstraint
    from pinstab.scene import scene_from_dict

    data = {"robot": {"urdf": str(DATA / "point_mass.urdf")}, "gravity": [0.0, -gravity, 0.0]}
    if initial is not None:
        data["initial"] = initial
    scene = scene_from_dict(data, name="pendulum")
    scene.add_constraint(
        HolonomicConstraint(
            "rod",
            1,
            residual=lambda q, t: np.array([q[0] ** 2 + q[1] ** 2 - length**2]),
            jacobian=lambda q, t: np.array([[2 * q[0], 2 * q[1]]]),
            drift=lambda q, v, t: np.array([2 * (v[0] ** 2 + v[1] ** 2)]),
            nv=2,
        )
    )
    return scene


# Hypothesis profiles of the fuzzers (tests/test_fuzz*.py), chosen by HYPOTHESIS_PROFILE: "default" (CI: each
# property's own bound, tests/fuzzing.py examples(); derandomized and without a database, so reproducible),
# "nightly" (2000 examples per property, random) or "long" (10,000 per property, random; README's development section).
HYPOTHESIS_PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "default")


def _register_hypothesis_profiles() -> None:
    """Register and load the Hypothesis settings profiles."""
    from hypothesis import HealthCheck, Phase, settings

    relaxed = dict(
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
        phases=[phase for phase in Phase if phase is not Phase.explain],  # explaining re-runs a failure dozens of times
    )
    settings.register_profile("default", max_examples=200, derandomize=True, database=None, print_blob=True, **relaxed)
    settings.register_profile("nightly", max_examples=2000, print_blob=True, **relaxed)
    settings.register_profile("long", max_examples=10_000, print_blob=True, **relaxed)
    settings.load_profile(HYPOTHESIS_PROFILE)


_register_hypothesis_profiles()


def with_python_force(scene):
    """The scene with a user's force element added (zero force, no compiled form): it keeps a compiled path's
    evaluation in Python (``kernel_obstacle`` names it)."""
    from pinstab.forces.base import ForceElement

    class UserForce(ForceElement):
        name = "user"
        needs_kinematics = False

        def generalized_force(self, kin, v: np.ndarray, t: float) -> np.ndarray:
            return np.zeros(len(v))

    scene.forces.append(UserForce())
    return scene


def bundled_with_force(scene: str, **changes):
    """The bundled scene ``robots/<scene>.toml`` with keys of its first ``[[forces]]`` table replaced."""
    import tomllib

    from pinstab.scene import scene_from_dict

    data = tomllib.loads((ROBOTS / f"{scene}.toml").read_text())
    data["forces"][0].update(changes)
    return scene_from_dict(data, base_dir=ROBOTS)


def assert_plan_solves_dynamics(scene, trajectory, k: int) -> None:
    """At sample k, the scene's controller (its first force element) plans the accelerations and constraint
    forces that pinstab's KKT system gives under its torques (dense solver, method none): 1e-8 [m/s^2,
    rad/s^2, N, N m]."""
    from pinstab.system import build_system

    q, v, t = trajectory.q[k], trajectory.v[k], float(trajectory.t[k])
    system = build_system(scene, "none", "dense")
    evaluation = system.dynamics(q, v, t)
    kin = system.model.kin
    kin.update(q, v)
    _, forces, acceleration = scene.forces[0].plan(kin, v, t)
    np.testing.assert_allclose(evaluation.acceleration, acceleration, rtol=0, atol=1e-8)
    np.testing.assert_allclose(evaluation.multipliers, forces, rtol=0, atol=1e-8)


def kicked_cassie():
    """The bundled ``cassie`` with its left knee motor turning at 1 rad/s at the start (benchmarks/cassie_implicit.py):
    its shin and heel-spring closures near-singular (the square root of G M^-1 G^T has singular values down to 9e-9
    of its largest)."""
    import tomllib

    from pinstab.scene import scene_from_dict

    data = tomllib.loads((ROBOTS / "cassie.toml").read_text())
    data["initial"] = {"v": {"left-knee-op": 1.0}}
    return scene_from_dict(data, base_dir=ROBOTS, name="cassie-kicked")


def pinocchio_closure_residuals(system, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each closure's and joint relation's position [m or rad] and velocity [m/s or rad/s] residuals from Pinocchio's
    frame placements and velocities (not pinstab's rows): frame b relative to frame a in a's axes, the translation
    and the twist's linear part for a point, and for a revolute (prismatic) closure also the rotation log3(R_a^T R_b)
    and the angular part across the axis (all of them; the translation and linear part across the axis); a joint
    relation's coefficients times q (less its target's value, zero here) and times v."""
    model = system.model
    data = model.createData()
    pin.forwardKinematics(model, data, q, v)
    pin.updateFramePlacements(model, data)
    positions, velocities = [], []
    for closure in system.constraints.constraints:
        if closure.kind == "joint-relation":
            positions.append(np.atleast_1d(closure.row @ q[closure.q_indices]))
            velocities.append(np.atleast_1d(closure.row @ v[closure.v_indices]))
            continue
        placement_a, placement_b = data.oMf[closure.frame_a], data.oMf[closure.frame_b]
        relative = placement_a.actInv(placement_b)
        twist = relative.act(pin.getFrameVelocity(model, data, closure.frame_b, pin.LOCAL))
        twist -= pin.getFrameVelocity(model, data, closure.frame_a, pin.LOCAL)
        turn = pin.log3(relative.rotation)
        if closure.kind == "point":
            positions.append(relative.translation)
            velocities.append(twist.linear)
        elif closure.kind == "revolute":
            positions += [relative.translation, closure.across @ turn]
            velocities += [twist.linear, closure.across @ twist.angular]
        else:
            positions += [closure.across @ relative.translation, turn]
            velocities += [closure.across @ twist.linear, twist.angular]
    return np.concatenate(positions), np.concatenate(velocities)
