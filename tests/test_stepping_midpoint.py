"""The time-stepping contacts' velocity terms at the midpoint of the step's velocities, impulses included
(pinstab/integration/contact_stepping.py, cpp/cone_step.cpp): a two-link finger pressed still onto a wall by constant
joint torques against the statics J^T F = -tau.

Measured (this file's scene, 12 N normal, 1 N tangential): with the velocity terms at the free step's midpoint
(v + v_free) / 2 the wall's normal force was 0.77 N off at dt = 2 ms and 0.18 N off at 1 ms, the tangential one 0.93 N
and 0.22 N off (the terms at the speed the torques would give the finger unopposed); at the midpoint of v and v+ it is
the statics' to 1.2e-10 N and 5.3e-10 N, the finger still to 7.6e-12 rad (the cone solve's tolerance).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pinstab.bench.python_stepper import PythonStepper
from pinstab.constraints.contacts import contact_basis
from pinstab.scene import scene_from_dict
from pinstab.simulate import simulate
from pinstab.simulate.contacts import stepping_parts
from pinstab.simulate.loop import start_state

LENGTHS, MASS = (0.05, 0.04), 0.02  # [m] the links, [kg] each
Q0 = np.array([0.3, 0.6])  # [rad]
WALL_FORCE = np.array([-12.0, 1.0, 0.0])  # [N] the wall's force on the fingertip, in the world
NORMAL = np.array([-1.0, 0.0, 0.0])  # the wall's normal, towards the finger


def _link(name: str, length: float) -> str:
    inertia = MASS * length**2 / 12
    return (
        f"<link name='{name}'><inertial><origin xyz='{length / 2} 0 0'/><mass value='{MASS}'/>"
        f"<inertia ixx='1e-7' iyy='{inertia}' izz='{inertia}' ixy='0' ixz='0' iyz='0'/></inertial></link>"
    )


def _joint(name: str, parent: str, child: str, x: float) -> str:
    return (
        f"<joint name='{name}' type='revolute'><parent link='{parent}'/><child link='{child}'/>"
        f"<origin xyz='{x} 0 0'/><axis xyz='0 0 1'/><limit lower='-3' upper='3' effort='10' velocity='10'/></joint>"
    )


URDF = (
    "<robot name='finger'><link name='base'/>"
    + _link("l1", LENGTHS[0])
    + _link("l2", LENGTHS[1])
    + "<link name='tip'/>"
    + _joint("j0", "base", "l1", 0.0)
    + _joint("j1", "l1", "l2", LENGTHS[0])
    + f"<joint name='tipj' type='fixed'><parent link='l2'/><child link='tip'/><origin xyz='{LENGTHS[1]} 0 0'/></joint>"
    + "</robot>"
)


def pressed_finger() -> dict:
    """The finger at :data:`Q0` with its tip on a wall and the joint torques -J^T F that the wall's force F =
    :data:`WALL_FORCE` balances (mu 1: F inside the cone)."""
    model = pin.buildModelFromXML(URDF)
    data = model.createData()
    tip = model.getFrameId("tip")
    pin.framesForwardKinematics(model, data, Q0)
    jacobian = pin.computeFrameJacobian(model, data, Q0, tip, pin.LOCAL_WORLD_ALIGNED)[:3]
    torques = -jacobian.T @ WALL_FORCE
    return {
        "gravity": [0.0, 0.0, -9.81],
        "robot": {"urdf_text": URDF},
        "initial": {"q": {"j0": Q0[0], "j1": Q0[1]}},
        "forces": [
            {"name": f"motor{j}", "kind": "joint-torque", "joint": f"j{j}", "torque": float(torques[j])} for j in (0, 1)
        ],
        "contacts": [
            {
                "name": "wall",
                "kind": "plane-contact",
                "frame_a": "tip",
                "normal": NORMAL.tolist(),
                "point": data.oMf[tip].translation.tolist(),
                "mu": 1.0,
            }
        ],
    }


@pytest.mark.parametrize("dt", [2e-3, 1e-3])
def test_a_finger_pressed_still_feels_the_statics(dt: float) -> None:
    """The finger stays still (1e-10 rad, 2e-9 rad/s) and the wall's force of its first step, the start event's, is
    the statics' (1e-9 N asserted)."""
    run = simulate(scene_from_dict(pressed_finger(), "finger"), contacts="stepping", dt=dt, duration=0.05)
    assert np.max(np.abs(run.q - Q0)) <= 1e-10 and np.max(np.abs(run.v)) <= 2e-9
    (event,) = run.info.contact_events
    assert event["to"] == "sticking"
    force = contact_basis(NORMAL).T @ np.array(event["force"])
    assert np.max(np.abs(force - WALL_FORCE)) <= 1e-9, force


def test_the_numpy_step_is_the_compiled_step() -> None:
    """The NumPy reference step (pinstab.bench.python_stepper, the second method), from the compiled run's state at
    every step: the same end state (1e-12) and impulses (1e-12 N s); the wall's force the statics' (1e-9 N)."""
    dt = 2e-3
    parts = []
    for stepper in (None, PythonStepper):
        scene = scene_from_dict(pressed_finger(), "finger")
        _, made, q, v = stepping_parts(scene, dt, *start_state(scene, None, None), *([stepper] if stepper else []))
        parts.append(made)
    compiled, reference = parts
    for k in range(25):
        expected = reference.step(q.copy(), v.copy(), k * dt, dt)
        q, v = compiled.step(q, v, k * dt, dt)
        assert np.max(np.abs(q - expected[0])) <= 1e-12 and np.max(np.abs(v - expected[1])) <= 1e-12
        np.testing.assert_allclose(compiled.impulses, reference.impulses, rtol=0, atol=1e-12)
        force = contact_basis(NORMAL).T @ (reference.impulses[0] / dt)
        assert np.max(np.abs(force - WALL_FORCE)) <= 1e-9, (k, force)
