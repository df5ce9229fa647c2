"""MJCF joint dynamics: ``damping``, ``stiffness``/``springref`` as ``joint-spring`` forces and ``armature`` against
MuJoCo's compiled model (dof_damping, jnt_stiffness, qpos_spring, dof_armature, its mass matrix and energy) and its
trajectory (contacts off, RK4 at 1e-4 s); the energy with a rotor on a joint of a non-coordinate axis; what is not
read noted by ``pinstab check``; a locked joint named like its body."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from mujoco_twin import largest_difference, mujoco, scene_of, twins, written

from conftest import FOURBAR_LOOP, ROBOTS
from pinstab import simulate
from pinstab.cli import main
from pinstab.errors import SceneError
from pinstab.model import ConstrainedModel
from pinstab.scene import scene_from_dict

# Each joint its own dynamics: a sprung, damped hinge in degrees (springref converted), a damped slide, a tilted
# hinge (an axis not a coordinate axis) with a rotor, the whole through <default> classes.
PASSIVE = """<mujoco model="passive">
  <compiler angle="degree"/>
  <option timestep="0.0001" integrator="RK4"><flag contact="disable"/></option>
  <default>
    <joint armature="0.003"/>
    <geom type="capsule" size="0.02 0.08"/>
    <default class="sprung"><joint stiffness="3" springref="25" damping="0.04"/></default>
  </default>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" class="sprung" axis="0 1 0"/>
      <geom pos="0 0 -0.1"/>
      <body name="slider" pos="0 0 -0.2">
        <joint name="slide" type="slide" axis="1 0 0" damping="0.3" stiffness="20" springref="0.05"/>
        <geom type="box" size="0.03 0.03 0.03"/>
        <body name="lower" pos="0 0 -0.05">
          <joint name="tilted" axis="0.6 0 0.8" armature="0.01"/>
          <geom fromto="0 0 0 0.1 0.05 -0.15" size="0.015"/>
        </body>
      </body>
    </body>
  </worldbody>
  <keyframe><key name="swing" qpos="0.4 0.02 -0.7" qvel="1 -0.2 3"/></keyframe>
</mujoco>
"""


@pytest.fixture
def passive(tmp_path: Path) -> Path:
    return written(tmp_path, "passive.xml", PASSIVE)


def test_springs_dampers_and_rotors_are_mujocos(passive: Path) -> None:
    scene, theirs = twins(passive)
    springs = {element.name: element for element in scene.forces}
    assert sorted(springs) == ["shoulder/spring", "slide/spring"]  # the tilted joint has none
    for name in ("shoulder", "slide"):
        joint = theirs.joint(name)
        spring = springs[f"{name}/spring"]
        assert spring.damping == theirs.dof_damping[joint.dofadr[0]]
        assert spring.stiffness == theirs.jnt_stiffness[joint.id]
        assert spring.reference == pytest.approx(theirs.qpos_spring[joint.qposadr[0]], abs=1e-15)
    np.testing.assert_array_equal(scene.model.armature, theirs.dof_armature)
    data, q = mujoco.MjData(theirs), np.array([0.3, -0.1, 1.2])
    data.qpos[:] = q
    mujoco.mj_forward(theirs, data)
    expected = np.zeros((3, 3))
    mujoco.mj_fullM(theirs, data, expected)
    ours = pin.crba(scene.model, scene.model.createData(), q)
    np.testing.assert_allclose(np.triu(ours) + np.triu(ours, 1).T, expected, atol=1e-12)


def test_energy_with_a_rotor_on_a_tilted_axis_is_mujocos(passive: Path) -> None:
    """Kinetic (rotors included), gravity and spring energy against MuJoCo's mj_energyPos + mj_energyVel to 1e-12 J;
    Pinocchio's own kinetic energy misses the tilted joint's rotor term (the 1 % drift that was not there)."""
    scene = scene_of(passive, keyframe="swing")
    theirs = mujoco.MjModel.from_xml_path(str(passive))
    data = mujoco.MjData(theirs)
    data.qpos[:], data.qvel[:] = scene.q0, scene.v0
    mujoco.mj_forward(theirs, data)
    mujoco.mj_energyPos(theirs, data)
    mujoco.mj_energyVel(theirs, data)
    model = ConstrainedModel(scene)
    model.kin.update_jacobians(scene.q0)
    assert model.energy(scene.q0, scene.v0) == pytest.approx(data.energy.sum(), abs=1e-12)
    pinocchio_alone = pin.computeKineticEnergy(scene.model, scene.model.createData(), scene.q0, scene.v0)
    assert abs(pinocchio_alone - data.energy[1]) > 1e-3  # the rotor's 0.5 * 0.01 * 3^2 = 0.045 J, or part of it


def test_conservative_run_with_a_rotor_keeps_its_energy(tmp_path: Path) -> None:
    """No damping, no springs: the run's energy series (4.87 J) is constant to 1e-8 J (measured 2.2e-9 J; it
    drifted by the order of the rotor's energy, 0.045 J)."""
    path = tmp_path / "rotor.xml"
    path.write_text(PASSIVE.replace('damping="0.04"', "").replace('damping="0.3"', ""))
    trajectory = simulate(scene_of(path, keyframe="swing"), duration=0.5, dt=0.01, rtol=1e-11, atol=1e-11)
    assert np.ptp(trajectory.energy) < 1e-8


def test_passive_robot_runs_as_mujoco(passive: Path) -> None:
    """From the keyframe, 1 s: pinstab (dop853, 1e-11) and MuJoCo (RK4, 1e-4 s) agree to 1e-8 rad or m (measured
    3e-10: no soft constraint between them, only the integrators' errors)."""
    difference = largest_difference(scene_of(passive, keyframe="swing"), mujoco.MjModel.from_xml_path(str(passive)))
    assert difference < 1e-8


@pytest.mark.parametrize(
    ("joint", "phrase"),
    [
        ('type="ball" stiffness="1"', "the stiffness of a ball joint is not read"),
        ('springdamper="0.1 1"', "springdamper='0.1 1'"),
        ('damping="-1"', "damping=-1.0 is negative"),
    ],
)
def test_joint_dynamics_pinstab_cannot_hold_are_refused_by_name(tmp_path: Path, joint: str, phrase: str) -> None:
    path = tmp_path / "bad.xml"
    path.write_text(
        f'<mujoco><worldbody><body name="a"><joint name="j" {joint}/><geom size="0.1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(SceneError, match="joint 'j'") as refused:
        scene_of(path)
    assert phrase in str(refused.value)


def test_check_lists_what_is_not_read(tmp_path: Path, capsys) -> None:
    """An MJCF with friction, soft limits, an actuator pinstab does not read (a cylinder), a soft equality of a
    <default> and a keyframe: every one is a note of ``pinstab check`` (its note list was empty)."""
    path = tmp_path / "robot.xml"
    path.write_text(
        '<mujoco><compiler angle="radian"/><default><equality solref="0.01 1"/><joint frictionloss="0.2" range="-1 1"/>'
        "</default>"
        '<worldbody><body name="a"><joint name="ja"/><geom size="0.1"/><body name="b"><joint name="jb" margin="0.1"/>'
        '<geom size="0.1"/></body></body></worldbody>'
        '<equality><joint name="pair" joint1="ja" joint2="jb"/></equality>'
        '<actuator><motor name="m" joint="ja"/><cylinder name="c" joint="jb"/></actuator>'
        '<keyframe><key name="k" qpos="0.1 0.1" ctrl="1 0"/></keyframe></mujoco>'
    )
    (tmp_path / "scene.toml").write_text('[robot]\nmjcf = "robot.xml"\n')
    assert main(["check", str(tmp_path / "scene.toml"), "--json"]) == 0
    notes = "\n".join(json.loads(capsys.readouterr().out)["robot_notes"])
    for phrase in (
        "joints 'ja', 'jb': their frictionloss is held as hard dry friction",
        "joints 'ja', 'jb': their ranges are held as hard limits",
        "joint margin of 'jb' not read",
        "solref/solimp/torquescale of equalities 'pair' ignored",
        "actuators not read (no force in the run): 'c' (<cylinder>)",
        "the start is keyframe 'k'",
    ):
        assert phrase in notes


def test_locked_joint_named_like_its_body(tmp_path: Path) -> None:
    """The bundled MJCF four-bar (bodies and joints share names) with its crank locked: read (it ended in
    Pinocchio's ValueError), the body frames kept by name, and it runs as the URDF four-bar locked alike."""
    q = {"crank": 1.0, "coupler": -0.9, "rocker": 1.6}
    runs = []
    for robot in ({"mjcf": str(ROBOTS / "mjcf/fourbar.xml")}, {"urdf": str(ROBOTS / "urdf/fourbar.urdf")}):
        closure = {"closures": [FOURBAR_LOOP]} if "urdf" in robot else {}  # the MJCF file's own: a connect
        scene = scene_from_dict(
            {"robot": {**robot, "locked_joints": ["crank"]}, "gravity": [0, -9.81, 0], "initial": {"q": q}, **closure}
        )
        assert scene.model.nq == 2 and scene.locked_joints == {"crank": 1.0}
        assert scene.model.existFrame("crank", pin.FrameType.BODY)
        runs.append(simulate(scene, duration=0.3, dt=0.01, rtol=1e-10, atol=1e-10).q)
    np.testing.assert_allclose(runs[0], runs[1], atol=1e-8)
