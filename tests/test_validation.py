"""Physical validity checked at load (pinstab.validation): each bad input is a SceneError naming the item."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import ROBOTS, fourbar_dict
from pinstab import SceneError, load_scene, readers
from pinstab.scene import scene_from_dict
from pinstab.validation import MAX_DEPTH, MAX_SCENE_BYTES

INERTIA = {"ixx": "0.1", "iyy": "0.1", "izz": "0.02", "ixy": "0", "ixz": "0", "iyz": "0"}


def pendulum_urdf(mass: str = "1", arm: str = "arm", root: str = "base", forearm: bool = True, **inertia: str) -> str:
    """A two-link pendulum: link ``arm`` on revolute joint ``shoulder``, link ``forearm`` (1 kg, or
    without an inertial when not ``forearm``) on ``elbow``."""
    values = " ".join(f'{k}="{v}"' for k, v in {**INERTIA, **inertia}.items())
    fixed = '<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial>'
    fixed = fixed if forearm else ""
    return f"""<robot name="pendulum">
  <link name="{root}"/>
  <link name="{arm}"><inertial><mass value="{mass}"/><inertia {values}/></inertial></link>
  <link name="forearm">{fixed}</link>
  <joint name="shoulder" type="revolute"><parent link="{root}"/><child link="{arm}"/><axis xyz="0 1 0"/>
    <limit effort="10" velocity="10" lower="-3" upper="3"/></joint>
  <joint name="elbow" type="revolute"><parent link="{arm}"/><child link="forearm"/><origin xyz="0 0 -1"/>
    <axis xyz="0 1 0"/><limit effort="10" velocity="10" lower="-3" upper="3"/></joint>
</robot>"""


def pendulum(urdf: str | None = None, **changes) -> dict:
    """Scene-file content of the pendulum (``robot`` keys merged from ``changes['robot']``)."""
    data = {"robot": {"urdf_text": urdf or pendulum_urdf(), **changes.pop("robot", {})}}
    data.update(changes)
    return data


FLOATING = {"free_flyer": True}


@pytest.mark.parametrize(
    ("data", "phrase"),
    [
        (pendulum(pendulum_urdf(mass="-1")), "robot link 'arm': mass -1.0 kg is negative"),
        (pendulum(pendulum_urdf(mass="nan")), "robot link 'arm': mass 'nan' is not a finite number"),
        (pendulum(pendulum_urdf(mass="1e400")), "robot link 'arm': mass '1e400' is not a finite number"),
        (pendulum(pendulum_urdf(ixx="heavy")), "robot link 'arm': inertia ixx 'heavy' is not a finite number"),
        (pendulum(pendulum_urdf(ixx="-0.5")), "robot link 'arm': inertia is not positive semidefinite"),
        (pendulum(pendulum_urdf(ixy="0.5")), "principal moments [-0.4, 0.02, 0.6] kg m^2"),
        (
            pendulum(pendulum_urdf(ixx="1", iyy="0.1", izz="0.1")),
            "robot link 'arm': inertia violates the triangle inequality: principal moments [0.1, 0.1, 1.0] kg m^2",
        ),
        (
            pendulum(pendulum_urdf(forearm=False)),
            "robot: joint 'elbow' (link forearm) moves no mass or inertia (zero mass and zero inertia on it and its "
            "descendants): the mass matrix is singular",
        ),
        (pendulum(pendulum_urdf(arm="world")), "frame 'world' (on joint 'shoulder') shadows pinstab's world frame"),
        (
            pendulum(pendulum_urdf(root="world"), robot=FLOATING),
            "frame 'world' (on joint 'root_joint') shadows pinstab's world frame",
        ),
        (
            pendulum(robot={"locked_joints": ["shoulder", "elbow"]}),
            "the model has no degree of freedom (nv = 0): every joint is locked",
        ),
        (
            pendulum(robot={"locked_joints": ["elbow", "shoulder", "elbow"]}),
            "robot.locked_joints: joint 'elbow' is listed more than once",
        ),
        (
            fourbar_dict(closures=[{"name": "self", "kind": "point", "frame_a": "coupler", "frame_b": "coupler"}]),
            "constraint 'self': both frames are on the same rigid body (joint 'coupler'): a closure between a frame "
            "and itself",
        ),
        (
            fourbar_dict(closures=[{"name": "grounded", "kind": "weld", "frame_a": "ground", "frame_b": "world"}]),
            "constraint 'grounded': both frames are on the same rigid body (joint 'universe')",
        ),
        (
            pendulum(robot=FLOATING, initial={"q": {"root_joint": [0, 0, 0, 0, 0, 0, 0]}}),
            "initial.q.root_joint: [0.0, 0.0, 0.0, 0.0] is not a unit quaternion or complex number (norm 0;",
        ),
        (
            pendulum(robot=FLOATING, initial={"q": {"root_joint": [0, 0, 0, 0, 0, 0, 2]}}),
            "(norm 2; only a norm within 0.001 of 1 is normalized)",
        ),
        (
            pendulum(robot=FLOATING, initial={"q": {"root_joint": [0, 0, 0, 0, 0, 0, float("nan")]}}),
            "initial.q.root_joint has a non-finite entry",
        ),
        (pendulum(initial={"q": {"shoulder": float("nan")}}), "initial.q.shoulder: value nan is not finite"),
        (
            pendulum(robot=FLOATING | {"locked_joints": ["root_joint"]}, initial={"q": {"root_joint": [0] * 7}}),
            "initial.q.root_joint: [0.0, 0.0, 0.0, 0.0] is not a unit quaternion",
        ),
        ({"robot": {"urdf_text": "<robot name='r'><link name='a'/>"}}, "robot: the URDF cannot be read"),
    ],
)
def test_bad_physical_input_is_refused(data: dict, phrase: str) -> None:
    with pytest.raises(SceneError) as info:
        scene_from_dict(data, base_dir=ROBOTS)
    assert phrase in str(info.value)


def test_rounded_quaternion_is_normalized() -> None:
    half = 0.7071  # cos 45 deg to 4 places: norm 0.99999
    scene = scene_from_dict(pendulum(robot=FLOATING, initial={"q": {"root_joint": [1, 2, 3, 0, 0, half, half]}}))
    assert np.linalg.norm(scene.q0[3:7]) == pytest.approx(1.0, abs=1e-15)
    assert scene.q0[5] == pytest.approx(np.sqrt(0.5), abs=1e-15)
    assert scene.q0[:3].tolist() == [1.0, 2.0, 3.0]


def test_world_link_at_the_world_origin_is_accepted() -> None:
    scene = scene_from_dict(pendulum(pendulum_urdf(root="world")))
    frame = scene.model.frames[scene.model.getFrameId("world")]
    assert frame.parentJoint == 0 and frame.placement.isIdentity()
    assert scene.model.nv == 2


def test_massless_link_is_accepted_when_its_joint_carries_mass() -> None:
    """A zero-mass link is fine when a child link gives its joint something to move."""
    scene = scene_from_dict(pendulum(pendulum_urdf(mass="0", ixx="0", iyy="0", izz="0")))
    assert scene.model.nv == 2


def test_example_robot_data_inertias_are_taken_as_published() -> None:
    """The Allegro hand's fingertips violate the triangle inequality: accepted by name, refused as URDF text."""
    scene = load_scene(ROBOTS / "allegro-box.toml")
    assert scene.model.nv > 0
    path, _ = readers.example_robot_urdf("allegro_right_hand")
    with pytest.raises(SceneError, match=r"robot link 'link_3.0': inertia violates the triangle inequality"):
        scene_from_dict({"robot": {"urdf_text": path.read_text()}})


# -- scene files ---------------------------------------------------------------------------------
def _write(tmp_path: Path, content: bytes) -> Path:
    path = tmp_path / "bad.toml"
    path.write_bytes(content)
    return path


@pytest.mark.parametrize(
    ("content", "phrase"),
    [
        (b'description = "caf\xe9"\n', "not UTF-8 text (byte 18: 0xe9)"),
        (b"# " + b"x" * MAX_SCENE_BYTES + b"\n", f"more than the limit of {MAX_SCENE_BYTES} bytes"),
        (b"a = " + b"[" * 5000 + b"]" * 5000 + b"\n", f"nested more than {MAX_DEPTH} levels deep"),
        (b"a = " + b"[" * (MAX_DEPTH + 1) + b"]" * (MAX_DEPTH + 1) + b"\n", f"nested more than {MAX_DEPTH} levels"),
        (b"a" + b".a" * MAX_DEPTH + b" = 1\n", f"nested more than {MAX_DEPTH} levels deep"),
        (b"robot = [\n", "not valid TOML"),
    ],
)
def test_bad_scene_file_is_refused(tmp_path: Path, content: bytes, phrase: str) -> None:
    path = _write(tmp_path, content)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert f"scene file {path}: " in str(info.value)
    assert phrase in str(info.value)


def test_nesting_up_to_the_limit_passes_the_depth_check(tmp_path: Path) -> None:
    """Nested MAX_DEPTH levels deep (the top table is one): the depth check lets it through to the schema."""
    path = _write(tmp_path, b"robto = " + b"[" * (MAX_DEPTH - 1) + b"]" * (MAX_DEPTH - 1) + b"\n")
    with pytest.raises(SceneError, match="unknown key 'robto'"):
        load_scene(path)


def test_deep_scene_dict_is_refused() -> None:
    deep: dict = {}
    node = deep
    for _ in range(10_000):
        node["a"] = {}
        node = node["a"]
    with pytest.raises(SceneError, match=f"scene deep: tables or arrays nested more than {MAX_DEPTH} levels deep"):
        scene_from_dict(deep, name="deep")


@pytest.mark.parametrize("path", sorted(ROBOTS.glob("*.toml")), ids=lambda p: p.stem)
def test_bundled_scenes_pass_the_checks(path: Path) -> None:
    scene = load_scene(path)
    assert scene.model.nv > 0
    assert np.all(np.isfinite(scene.q0))
