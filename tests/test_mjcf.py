"""MJCF robots (pinstab.readers.mjcf): the four-bar against its URDF twin, the equalities against MuJoCo's own
reading of the same file (its compiled eq_data, site and body poses, equality residuals), joint limits against
MuJoCo's jnt_range, and bad input."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from conftest import ROBOTS
from pinstab import simulate
from pinstab.cli import main
from pinstab.constraints.joint_limits import joint_limits
from pinstab.errors import SceneError
from pinstab.kinematics import Kinematics
from pinstab.readers import read_robot
from pinstab.scene import load_scene, scene_from_dict

mujoco = pytest.importorskip("mujoco")

# Rotated bodies, joint refs, a site of <worldbody> (which Pinocchio's parser drops), every equality form.
GAPS = """<mujoco model="gaps">
  <compiler angle="degree"/>
  <default><joint range="-90 45"/><default class="free"><joint limited="false"/></default></default>
  <worldbody>
    <site name="world_site" pos="0.3 -0.2 1.4" quat="0.9 0.1 0.2 0.3"/>
    <body name="base" pos="0 0 0.1" euler="0 0 30">
      <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
      <body name="a" pos="0 0 1" euler="10 20 30">
        <joint name="ja" type="hinge" axis="0 1 0" ref="17"/>
        <inertial pos="0.5 0 0" mass="1" diaginertia="0.1 0.2 0.3"/>
        <site name="sa" pos="1 0 0" euler="0 0 30"/>
        <body name="b" pos="1 0 0.2" euler="5 0 -15">
          <joint name="jb" type="hinge" axis="1 0 1" class="free"/>
          <inertial pos="0.5 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
          <site name="sb" pos="1 0 0.1"/>
          <body name="e" pos="0.2 0.3 0" axisangle="0.6 0.8 0 30">
            <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
            <site name="se" pos="0 0 0.3" quat="0.5 0.5 0.5 0.5"/>
          </body>
        </body>
      </body>
      <body name="c" pos="2 0 0" euler="0 40 0">
        <joint name="jc" type="slide" axis="0 0 1" ref="0.05" range="-0.1 0.2"/>
        <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
        <site name="sc" pos="0 0 0.2" euler="10 0 0"/>
        <body name="d" pos="0 0.5 0">
          <joint name="jd" type="hinge" axis="1 0 0" limited="false" range="-10 10"/>
          <inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>
        </body>
      </body>
    </body>
  </worldbody>
  <equality>
    <connect name="to_world" body1="b" body2="world" anchor="1 0 0"/>
    <connect body1="b" anchor="0.5 0.1 0"/>
    <connect name="two_bodies" body1="b" body2="c" anchor="1 0 0"/>
    <connect name="by_sites" site1="sb" site2="sc" solref="0.02 1"/>
    <connect name="world_site" site1="sb" site2="world_site"/>
    <weld name="weld_ref" body1="b" body2="c"/>
    <weld name="weld_relpose" body1="a" body2="d" relpose="0.1 0.2 0.3 0.9 0.1 0.2 0.3"/>
    <weld name="weld_sites" site1="sa" site2="sc"/>
    <joint name="coupling" joint1="jb" joint2="jc" polycoef="0.1 2 0 0 0"/>
    <joint joint1="jd" polycoef="0.2 0 0 0 0"/>
    <weld name="static_body" site1="se" site2="world_site"/>
  </equality>
</mujoco>
"""
NAMES = [
    "to_world",
    "connect1",
    "two_bodies",
    "by_sites",
    "world_site",
    "weld_ref",
    "weld_relpose",
    "weld_sites",
    "coupling",
    "joint1",
    "static_body",
]
TOL = 1e-12  # [m, rad]: the same kinematics evaluated twice, by two libraries


@pytest.fixture
def gaps(tmp_path):
    """(the file, its pinstab scene, MuJoCo's model) of :data:`GAPS`."""
    path = tmp_path / "gaps.xml"
    path.write_text(GAPS)
    scene = scene_from_dict({"robot": {"mjcf": str(path)}}, base_dir=tmp_path)
    return path, scene, mujoco.MjModel.from_xml_path(str(path))


def _mujoco_state(model, q: np.ndarray):
    data = mujoco.MjData(model)
    data.qpos[:] = q  # hinge and slide joints only: the two libraries' coordinates agree (MuJoCo's qpos0 = ref)
    mujoco.mj_forward(model, data)
    return data


def _pose(position: np.ndarray, matrix: np.ndarray) -> pin.SE3:
    return pin.SE3(np.asarray(matrix).reshape(3, 3), np.asarray(position))


def _relpose(eq_data: np.ndarray) -> pin.SE3:
    w, x, y, z = eq_data[6:10]
    return pin.SE3(pin.Quaternion(w, x, y, z).normalized().matrix(), eq_data[3:6])


def _side(scene, data, name: str, side: str) -> pin.SE3:
    """World placement of a closure's side in pinstab's model (the world side: its fixed placement)."""
    if scene.model.existFrame(f"{name}/{side}"):
        return data.oMf[scene.model.getFrameId(f"{name}/{side}")]
    closure = next(c for c in scene.constraints if c.name == name)
    return closure.world_placement_b


def _expected_sides(model, data, name: str) -> tuple[pin.SE3, pin.SE3]:
    """The two sides' world placements as MuJoCo reads the equality (site or body frames and its eq_data)."""
    eq = NAMES.index(name)  # MuJoCo numbers the equalities in the file's order
    objects = model.eq_obj1id[eq], model.eq_obj2id[eq]
    if model.eq_objtype[eq] == mujoco.mjtObj.mjOBJ_SITE:
        return tuple(_pose(data.site_xpos[i], data.site_xmat[i]) for i in objects)
    body1, body2 = (_pose(data.xpos[i], data.xmat[i]) for i in objects)
    if model.eq_type[eq] == mujoco.mjtEq.mjEQ_CONNECT:  # eq_data: anchor in body1, its point in body2
        anchor1, anchor2 = model.eq_data[eq][0:3], model.eq_data[eq][3:6]
        return pin.SE3(np.eye(3), body1.act(anchor1)), pin.SE3(np.eye(3), body2.act(anchor2))
    return body1 * _relpose(model.eq_data[eq]), body2  # weld: body2's pose in body1


def _close(a: pin.SE3, b: pin.SE3, rotation: bool) -> bool:
    same_rotation = np.abs(a.rotation - b.rotation).max() <= TOL
    return np.abs(a.translation - b.translation).max() <= TOL and (same_rotation or not rotation)


# -- the bundled four-bar ------------------------------------------------------------------------------------
def test_fourbar_mjcf_is_the_urdf_fourbar():
    mjcf, urdf = load_scene("fourbar-mjcf"), load_scene("fourbar")
    assert list(mjcf.model.names) == list(urdf.model.names)
    for joint in range(1, urdf.model.njoints):
        assert mjcf.model.inertias[joint] == urdf.model.inertias[joint]
        assert mjcf.model.jointPlacements[joint] == urdf.model.jointPlacements[joint]
    np.testing.assert_array_equal(mjcf.q0, urdf.q0)
    np.testing.assert_array_equal(mjcf.v0, urdf.v0)
    assert joint_limits(mjcf.model).limits == joint_limits(urdf.model).limits == []  # pin joints: no limits
    assert [c.name for c in mjcf.constraints] == ["coupler-rocker"]
    assert len(mjcf.robot.geometry(mjcf.model, pin.GeometryType.VISUAL, []).geometryObjects) == 3


@pytest.mark.parametrize("method", ["baumgarte", "projection", "pinocchio"])
def test_fourbar_mjcf_trajectory_equals_the_urdf_fourbar(method):
    # fourbar-mjcf's connect is a 3-row point closure where fourbar has a 2-row planar one: the third (z) row is
    # identically zero in the plane, so the two runs differ only by rounding (with baumgarte, measured by this
    # comparison: 2.8e-13 rad in q, 2.5e-12 rad/s in v of at most 21.5 rad/s; with pinocchio: equal)
    urdf = simulate("fourbar", method=method, duration=2.0)
    mjcf = simulate("fourbar-mjcf", method=method, duration=2.0)
    np.testing.assert_array_equal(mjcf.t, urdf.t)
    assert np.abs(mjcf.q - urdf.q).max() <= TOL
    assert np.abs(mjcf.v - urdf.v).max() <= TOL * np.abs(urdf.v).max()


# -- the equalities, against MuJoCo --------------------------------------------------------------------------
def test_equality_names_are_kept_and_unnamed_ones_named(gaps):
    _, scene, _ = gaps
    assert [c.name for c in scene.constraints] == NAMES
    assert "equality <connect> number 1 has no name: named 'connect1'" in scene.robot.notes
    assert "equality <joint> number 1 has no name: named 'joint1'" in scene.robot.notes


@pytest.mark.parametrize("name", [n for n in NAMES if n not in ("coupling", "joint1")])
def test_closure_sides_match_mujoco(gaps, name):
    """World as body2 (to_world, connect1), a two-body connect, sites (one of <worldbody>), welds: at random
    configurations each side of pinstab's closure sits where MuJoCo puts it."""
    _, scene, model = gaps
    data = scene.model.createData()
    rng = np.random.default_rng(3)
    weld = name.startswith("weld") or name == "static_body"
    for _ in range(5):
        q = rng.uniform(-1.0, 1.0, scene.model.nq)
        pin.framesForwardKinematics(scene.model, data, q)
        expected_a, expected_b = _expected_sides(model, _mujoco_state(model, q), name)
        side_a, side_b = _side(scene, data, name, "a"), _side(scene, data, name, "b")
        assert _close(side_a, expected_a, weld) and _close(side_b, expected_b, weld), name


def test_connect_to_world_keeps_world_as_body2(gaps):
    _, scene, model = gaps
    for name in ("to_world", "connect1"):
        closure = next(c for c in scene.constraints if c.name == name)
        assert closure.kind == "point" and closure.frame_b is None
        eq = NAMES.index(name)
        np.testing.assert_allclose(closure.world_placement_b.translation, model.eq_data[eq][3:6], rtol=0, atol=TOL)


def test_two_body_connect_reads_both_bodies(gaps):
    _, scene, _ = gaps
    closure = next(c for c in scene.constraints if c.name == "two_bodies")
    joints = [scene.model.frames[f].parentJoint for f in (closure.frame_a, closure.frame_b)]
    assert [scene.model.names[j] for j in joints] == ["jb", "jc"]


def test_joint_equalities_are_joint_relations_with_mujocos_residual(gaps):
    _, scene, model = gaps
    relations = {c.name: c for c in scene.constraints if c.kind == "joint-relation"}
    kin = Kinematics(scene.model, scene.model.createData())  # a relation reads no kinematics, but takes them
    rng = np.random.default_rng(5)
    for _ in range(5):
        q = rng.uniform(-1.0, 1.0, scene.model.nq)
        state = _mujoco_state(model, q)
        equality_rows = state.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        residuals = dict(zip(state.efc_id[equality_rows], state.efc_pos[equality_rows], strict=False))
        for name, relation in relations.items():
            assert abs(relation.residual(kin, q, 0.0)[0] - residuals[NAMES.index(name)]) <= TOL, name


def test_soft_parameters_are_reported_as_ignored_by_check(tmp_path, capsys):
    fourbar = (ROBOTS / "mjcf" / "fourbar.xml").read_text()
    (tmp_path / "fourbar.xml").write_text(fourbar.replace('site2="rocker_tip"', 'site2="rocker_tip" solref="0.02 1"'))
    scene = (ROBOTS / "fourbar-mjcf.toml").read_text().replace("mjcf/fourbar.xml", "fourbar.xml")
    (tmp_path / "soft.toml").write_text(scene)
    assert main(["check", str(tmp_path / "soft.toml"), "--json"]) in (0, None)
    notes = json.loads(capsys.readouterr().out)["robot_notes"]
    assert any("'coupler-rocker'" in note and "solref" in note and "--method" in note for note in notes)


# -- joint limits, against MuJoCo -----------------------------------------------------------------------------
def test_joint_limits_match_mujoco(gaps):
    _, scene, model = gaps
    for joint in range(model.njnt):
        index = scene.model.joints[scene.model.getJointId(model.joint(joint).name)].idx_q
        bounds = scene.model.lowerPositionLimit[index], scene.model.upperPositionLimit[index]
        if model.jnt_limited[joint]:
            np.testing.assert_allclose(bounds, model.jnt_range[joint], rtol=0, atol=TOL)
        else:
            assert bounds == (-np.inf, np.inf)
    assert model.jnt_limited.tolist() == [1, 0, 1, 0]  # ja by the default class, jb by class "free", jc, jd


def test_limits_of_a_composite_joint_match_mujoco(tmp_path):
    """A body with several joints is one composite joint in Pinocchio: each joint's range at its coordinate."""
    joints = '<joint name="ja" type="hinge" axis="0 1 0" ref="17"/><joint name="jy" type="slide" range="-0.3 0.4"/>'
    robot = _read(tmp_path, _replaced('<joint name="ja" type="hinge" axis="0 1 0" ref="17"/>', joints))
    reference = mujoco.MjModel.from_xml_path(str(tmp_path / "robot.xml"))
    assert any("ja, jy are one composite joint" in note for note in robot.notes)
    limited = reference.jnt_limited.astype(bool)
    np.testing.assert_allclose(robot.model.lowerPositionLimit[limited], reference.jnt_range[limited, 0], atol=TOL)
    np.testing.assert_allclose(robot.model.upperPositionLimit[limited], reference.jnt_range[limited, 1], atol=TOL)
    assert np.isinf(robot.model.upperPositionLimit[~limited]).all()


# -- bad input --------------------------------------------------------------------------------------------------
def _read(tmp_path, text: str):
    (tmp_path / "robot.xml").write_text(text)
    return read_robot({"mjcf": "robot.xml"}, tmp_path)


def _replaced(old: str, new: str) -> str:
    assert old in GAPS
    return GAPS.replace(old, new)


@pytest.mark.parametrize(
    ("text", "named"),
    [
        (_replaced('site2="sc" solref', 'site2="nowhere" solref'), "'nowhere'"),
        (_replaced('body2="c" anchor', 'body2="ghost" anchor'), "'ghost'"),
        (_replaced('joint2="jc"', 'joint2="jz"'), "'jz'"),
        (_replaced('polycoef="0.1 2 0 0 0"', 'polycoef="0.1 2 0.5 0 0"'), "'coupling'"),
        (_replaced("<worldbody>", '<worldbody><body name="loose"><geom size="0.1"/></body>'), "'base'"),
        (_replaced('<connect name="to_world"', '<tendon name="t1"/><connect name="to_world"'), "'t1'"),
        (_replaced('axisangle="0.6 0.8 0 30"', 'axisangle="1 1 0 30"'), "'e'"),
        (GAPS[:200], "not valid XML"),
        ("<robot/>", "<robot>"),
    ],
    ids=[
        "missing-site",
        "missing-body",
        "missing-joint",
        "quadratic",
        "dropped-body",
        "tendon",
        "axis-not-unit",
        "malformed",
        "root",
    ],
)
def test_bad_mjcf_is_a_named_scene_error(tmp_path, text, named):
    with pytest.raises(SceneError, match=named):
        _read(tmp_path, text)


def test_missing_mjcf_file_is_a_scene_error(tmp_path):
    with pytest.raises(SceneError, match="does not exist"):
        read_robot({"mjcf": "absent.xml"}, tmp_path)


def test_copies_are_refused_for_mjcf(tmp_path):
    with pytest.raises(SceneError, match="copies"):
        read_robot({"mjcf": str(ROBOTS / "mjcf" / "fourbar.xml"), "copies": [{"prefix": "x_"}]}, tmp_path)


def test_static_root_body_and_its_geometry_sit_at_its_pose(tmp_path):
    """Pinocchio's parser leaves a static first body of <worldbody> at the origin ('base' is at 0.1 m, turned 30
    deg): its geom must sit where MuJoCo puts it."""
    plate = '<geom name="plate" type="box" size="0.1 0.2 0.3" pos="0.4 0 0"/>\n      <body name="a"'
    robot = _read(tmp_path, _replaced('<body name="a"', plate))
    geometry = robot.geometry(robot.model, pin.GeometryType.VISUAL, [])
    placed = next(g for g in geometry.geometryObjects if g.parentJoint == 0)
    reference = mujoco.MjModel.from_xml_path(str(tmp_path / "robot.xml"))
    state = _mujoco_state(reference, reference.qpos0)
    geom = mujoco.mj_name2id(reference, mujoco.mjtObj.mjOBJ_GEOM, "plate")
    np.testing.assert_allclose(placed.placement.translation, state.geom_xpos[geom], rtol=0, atol=TOL)
    np.testing.assert_allclose(placed.placement.rotation.ravel(), state.geom_xmat[geom], rtol=0, atol=TOL)
