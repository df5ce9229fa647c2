"""MJCF keyframes as the start: the first by default, one by name (``robot.keyframe``, ``load_scene(keyframe=)``,
``--keyframe``), MuJoCo's qpos0 without one; free and ball joints' quaternions and a free joint's velocity carried
to Pinocchio's coordinates, checked by the bodies' world poses and velocities against MuJoCo's at the key."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from mujoco_twin import mujoco, scene_of, written

from pinstab.cli import main
from pinstab.errors import SceneError
from pinstab.scene import load_scene, scene_from_dict

FLOATING = """<mujoco model="floating">
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 1">
      <freejoint name="root"/>
      <geom type="box" size="0.1 0.05 0.02"/>
      <body name="arm" pos="0.1 0 0">
        <joint name="ball" type="ball"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02"/>
        <body name="hand" pos="0.2 0 0">
          <joint name="wrist" axis="0 0 1" ref="0.3" range="-1 1"/>
          <geom size="0.03"/>
        </body>
      </body>
    </body>
  </worldbody>
  <keyframe>
    <key name="tumble" qpos="0.1 -0.2 1.3 0.8 0.2 -0.3 0.4 0.9 0.1 0.3 -0.2 0.5"
         qvel="0.3 -0.1 0.2 1 -2 0.5 0.4 0.2 -0.6 1.5"/>
    <key name="still" qpos="0 0 1 1 0 0 0 1 0 0 0 -0.5"/>
  </keyframe>
</mujoco>
"""


@pytest.fixture
def floating(tmp_path: Path) -> Path:
    return written(tmp_path, "floating.xml", FLOATING)


def _world(scene, name: str, q: np.ndarray, v: np.ndarray) -> tuple[pin.SE3, np.ndarray]:
    model = scene.model
    data = model.createData()
    pin.forwardKinematics(model, data, q, v)
    pin.updateFramePlacements(model, data)
    frame = model.getFrameId(name, pin.FrameType.BODY)
    velocity = pin.getFrameVelocity(model, data, frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    return data.oMf[frame], velocity.vector


@pytest.mark.parametrize("key", ["tumble", "still"])
def test_keyframe_bodies_are_where_mujoco_puts_them(floating: Path, key: str) -> None:
    scene = scene_of(floating, keyframe=key)
    theirs = mujoco.MjModel.from_xml_path(str(floating))
    data = mujoco.MjData(theirs)
    mujoco.mj_resetDataKeyframe(theirs, data, theirs.key(key).id)
    mujoco.mj_forward(theirs, data)
    for body in ("base", "arm", "hand"):
        pose, velocity = _world(scene, body, scene.q0, scene.v0)
        index = theirs.body(body).id
        np.testing.assert_allclose(pose.translation, data.xpos[index], atol=1e-12)
        np.testing.assert_allclose(pose.rotation, data.xmat[index].reshape(3, 3), atol=1e-12)
        twist = np.zeros(6)  # MuJoCo's: angular, linear of the body's origin, world frame
        mujoco.mj_objectVelocity(theirs, data, mujoco.mjtObj.mjOBJ_XBODY, index, twist, 0)
        np.testing.assert_allclose(velocity, np.concatenate([twist[3:], twist[:3]]), atol=1e-12)


def test_first_keyframe_is_the_default_start(floating: Path) -> None:
    scene = scene_of(floating)
    assert np.array_equal(scene.q0, scene_of(floating, keyframe="tumble").q0)
    assert "the start is keyframe 'tumble' (robot.keyframe or --keyframe names another key)" in scene.robot.notes


def test_without_keyframes_the_start_is_mujocos_qpos0(floating: Path) -> None:
    """Every joint at its ``ref`` (the wrist at 0.3 rad), at rest: Pinocchio's q = 0 put the body elsewhere."""
    text = FLOATING[: FLOATING.index("  <keyframe>")] + "</mujoco>\n"
    floating.write_text(text)
    scene = scene_of(floating)
    theirs = mujoco.MjModel.from_xml_path(str(floating))
    assert scene.q0[-1] == pytest.approx(theirs.qpos0[-1]) == pytest.approx(0.3)
    assert not scene.v0.any()


def test_keyframe_by_name_in_api_scene_and_cli(floating: Path, capsys) -> None:
    scene_file = floating.parent / "scene.toml"
    scene_file.write_text('[robot]\nmjcf = "floating.xml"\nkeyframe = "still"\n')
    still = scene_of(floating, keyframe="still").q0
    assert np.array_equal(load_scene(scene_file).q0, still)
    assert np.array_equal(load_scene(scene_file, keyframe="tumble").q0, scene_of(floating).q0)  # the API's wins
    assert main(["check", str(scene_file), "--keyframe", "tumble", "--json"]) == 0
    assert (
        "the start is keyframe 'tumble' (robot.keyframe or --keyframe names another key)"
        in json.loads(capsys.readouterr().out)["robot_notes"]
    )


def test_unknown_keyframe_is_a_scene_error_listing_the_keys(floating: Path) -> None:
    with pytest.raises(SceneError, match="robot.keyframe 'home' is not a key of .*keyframes: still, tumble"):
        scene_of(floating, keyframe="home")


def test_keyframe_of_a_urdf_robot_is_refused(data_dir: Path) -> None:
    with pytest.raises(SceneError, match="keyframes are read from MJCF files"):
        scene_from_dict({"robot": {"urdf": "body.urdf", "keyframe": "home"}}, base_dir=data_dir)


def test_keyframe_of_another_size_is_named(floating: Path) -> None:
    floating.write_text(FLOATING.replace('qpos="0 0 1 1 0 0 0 1 0 0 0 -0.5"', 'qpos="0 0 1"'))
    with pytest.raises(SceneError, match="keyframe 'still': qpos='0 0 1' is not 12 finite numbers"):
        scene_of(floating, keyframe="still")
