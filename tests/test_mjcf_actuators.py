"""MJCF actuators read as MuJoCo reads them (``joint-actuator`` forces): a motor with a gear and a clipped control,
a position servo whose force saturates, a velocity servo and an affine ``<general>``, from a keyframe's controls or
the scene's ``robot.ctrl``, each run beside MuJoCo's run of the same file (contacts off, RK4 at 0.1 ms)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mujoco_twin import largest_difference, mujoco, twins, written

from pinstab import load_scene
from pinstab.errors import SceneError
from pinstab.forces.base import batched
from pinstab.forces.joint_actuator import JointActuators
from pinstab.model import ConstrainedModel
from pinstab.scene import scene_from_dict

ARM = """<mujoco>
  <compiler angle="radian"/>
  <option timestep="1e-4" integrator="RK4"><flag contact="disable"/></option>
  <default><position kp="20" kv="1" forcerange="-2 2"/></default>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" mass="1.2"/>
      <body name="fore" pos="0.4 0 0">
        <joint name="elbow" axis="0 0.6 0.8"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="0.7"/>
        <body name="hand" pos="0.3 0 0">
          <joint name="wrist" axis="1 0 0" damping="0.02"/>
          <geom type="box" size="0.05 0.03 0.02" pos="0.05 0.02 0" mass="0.3"/>
          <body name="finger" pos="0.1 0 0">
            <joint name="slide" type="slide" axis="1 0 0"/>
            <geom type="sphere" size="0.02" mass="0.1"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="shoulder_servo" joint="shoulder"/>
    <velocity name="elbow_damper" joint="elbow" kv="0.5"/>
    <motor name="wrist_motor" joint="wrist" gear="0.02" ctrlrange="-0.5 0.5"/>
    <general name="finger_general" joint="slide" gainprm="3" biastype="affine" biasprm="0.1 -20 -0.3"/>
  </actuator>
  <keyframe><key name="reach" qpos="0.3 -0.2 0.1 0.02" ctrl="1.2 1 3 0.05"/></keyframe>
</mujoco>
"""
KEY_CTRL = np.array([1.2, 1.0, 3.0, 0.05])


@pytest.fixture
def arm(tmp_path: Path) -> Path:
    return written(tmp_path, "arm.xml", ARM)


def test_each_actuator_is_a_joint_actuator_with_mujocos_law(arm: Path) -> None:
    """The four actuators become joint-actuator forces (gain, bias, gear, ranges from the classes) whose joint torque
    equals MuJoCo's qfrc_actuator at the keyframe's state and controls to 1e-12 (the position servo saturated at
    its force range, the motor's control clipped; the class's forcerange, given on a <position> default, limits every
    actuator of the class as MuJoCo's shared actuator default does)."""
    scene, model = twins(arm)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    data.qvel[:] = [0.4, -1.1, 2.0, 0.3]
    mujoco.mj_forward(model, data)
    from pinstab.model import ConstrainedModel

    constrained = ConstrainedModel(scene)
    kin = constrained.scratch_kinematics
    kin.update(scene.q0, data.qvel.copy())
    ours = sum(force.generalized_force(kin, data.qvel.copy(), 0.0) for force in scene.forces[1:])
    assert [force.name for force in scene.forces] == [
        "wrist/spring",
        "shoulder_servo",
        "elbow_damper",
        "wrist_motor",
        "finger_general",
    ]
    np.testing.assert_allclose(ours, data.qfrc_actuator, rtol=0, atol=1e-12)
    assert abs(data.actuator_force[0]) == 2.0 and data.ctrl[2] == 3.0  # saturated servo, clipped motor control


def test_the_model_evaluates_its_actuators_at_once_as_one_by_one(tmp_path: Path) -> None:
    """The model's applied force takes the arm's actuators (with a second one, a motor, on the shoulder) in one
    evaluation in the first one's place (:func:`~pinstab.forces.base.batched`): MuJoCo's qfrc_actuator plus the wrist
    spring's torque to 1e-12 at the keyframe's state, and to the bit the sum of the elements evaluated one by one in
    their order at 30 random states (the servo saturated or not, the motor's control clipped)."""
    second = '<motor name="shoulder_motor" joint="shoulder" gear="2" ctrlrange="-1 1"/>\n    <velocity name="elbow'
    text = ARM.replace('<velocity name="elbow', second).replace('ctrl="1.2 1 3', 'ctrl="1.2 5 1 3')
    path = written(tmp_path, "arm.xml", text)
    scene, model = twins(path)
    constrained = ConstrainedModel(scene)
    spring, actuators = batched(scene.forces)
    assert spring is scene.forces[0] and isinstance(actuators, JointActuators)
    assert actuators.name == "shoulder_servo, shoulder_motor, elbow_damper, wrist_motor, finger_general"
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    data.qvel[:] = [0.4, -1.1, 2.0, 0.3]
    mujoco.mj_forward(model, data)
    kin = constrained.kin
    kin.update(scene.q0, data.qvel.copy())
    at_once = constrained.applied_force(data.qvel.copy(), 0.0)
    alone = spring.generalized_force(kin, data.qvel.copy(), 0.0)
    np.testing.assert_allclose(at_once - alone, data.qfrc_actuator, rtol=0, atol=1e-12)
    rng = np.random.default_rng(3)
    for _ in range(30):
        q, v = rng.uniform(-1.0, 1.0, 4), rng.uniform(-3.0, 3.0, 4)
        kin.update(q, v)
        one_by_one = np.zeros(4)
        for element in scene.forces:
            one_by_one += element.generalized_force(kin, v, 0.0)
        assert np.array_equal(constrained.applied_force(v, 0.0), one_by_one)


def test_hand_cube_servos_at_once_follow_their_tables_as_one_by_one() -> None:
    """hand-cube's six position servos, each driven by a time table, evaluated at once give the sum of each evaluated
    alone to the bit at times before, inside and after their tables' points; at rest on their targets (q = u,
    qdot = 0) the servos push their constant bias alone (the wrist's lift, 3.5316 N: the hand's weight), to 1e-12."""
    scene = load_scene("hand-cube")
    constrained = ConstrainedModel(scene)
    (actuators,) = batched(scene.forces)
    kin = constrained.kin
    rng = np.random.default_rng(5)
    for t in [-1.0, 0.0, 0.05, 0.3, 0.42, 1.0, 1.21, 1.7, 2.09, 5.0]:
        q = scene.q0 + rng.uniform(-0.05, 0.05, scene.model.nq)
        v = rng.uniform(-0.5, 0.5, scene.model.nv)
        kin.update(q, v)
        one_by_one = np.zeros(scene.model.nv)
        for element in scene.forces:
            one_by_one += element.generalized_force(kin, v, t)
        assert np.array_equal(actuators.generalized_force(kin, v, t), one_by_one)
        assert np.array_equal(constrained.applied_force(v, t), one_by_one)
    targets = np.array([element.control(0.6) for element in scene.forces])
    q = scene.q0.copy()
    q[[element.q_index for element in scene.forces]] = targets
    kin.update(q, np.zeros(scene.model.nv))
    lift = np.zeros(scene.model.nv)
    lift[[element.dof for element in scene.forces]] = [element.bias[0] for element in scene.forces]
    assert np.count_nonzero(lift) == 1 and lift[2] == 3.5316
    np.testing.assert_allclose(constrained.applied_force(np.zeros(scene.model.nv), 0.6), lift, rtol=0, atol=1e-12)


def test_the_arm_runs_as_mujoco_from_the_keyframes_controls(arm: Path) -> None:
    """From the keyframe (its qpos and ctrl): within 1e-6 rad of MuJoCo's RK4 run over 1 s (measured 1.2e-8 rad;
    no equality: the difference is the two integrators'). Without the class's force range on the general actuator
    (MuJoCo's shared actuator default) they parted by 0.5 rad at 0.5 s."""
    scene, model = twins(arm)
    assert largest_difference(scene, model, ctrl=KEY_CTRL) <= 1e-6


def test_robot_ctrl_overrides_the_keyframe(arm: Path) -> None:
    """robot.ctrl sets one actuator's control (the rest from the keyframe): MuJoCo's run with the same controls."""
    scene, model = twins(arm, ctrl={"wrist_motor": -0.2})
    assert largest_difference(scene, model, ctrl=np.array([1.2, 1.0, -0.2, 0.05])) <= 1e-6


@pytest.mark.parametrize(
    ("robot", "phrase"),
    [
        ({"ctrl": {"gripper": 1.0}}, "'gripper' not an actuator of"),
        ({"ctrl": [1.0]}, "robot.ctrl must be a table"),
        ({"ctrl": {"wrist_motor": "fast"}}, "wrist_motor"),
    ],
)
def test_bad_controls_are_named(arm: Path, robot: dict, phrase: str) -> None:
    with pytest.raises(SceneError, match=phrase):
        scene_from_dict({"robot": {"mjcf": arm.name, **robot}}, base_dir=arm.parent)


def test_ctrl_on_a_urdf_robot_is_refused() -> None:
    with pytest.raises(SceneError, match="robot.ctrl: actuators' controls are read from MJCF files"):
        scene_from_dict({"robot": {"urdf": "urdf/fourbar.urdf", "ctrl": {"m": 1.0}}})


def test_a_bad_number_in_an_actuator_is_named(tmp_path: Path) -> None:
    """A dampratio that is not a number is a SceneError naming the actuator and the attribute (it was a raw
    ValueError)."""
    path = written(
        tmp_path,
        "arm.xml",
        ARM.replace('<position name="shoulder_servo"', '<position dampratio="x" name="shoulder_servo"'),
    )
    with pytest.raises(SceneError, match="actuator 'shoulder_servo': dampratio='x' is not a list of numbers"):
        scene_from_dict({"robot": {"mjcf": path.name}}, base_dir=path.parent)
