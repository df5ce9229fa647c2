"""MJCF ``<default>`` classes (nested, ``childclass``, ``class=``) read as MuJoCo reads them: each joint's anchor,
axis and the spatial inertia of the bodies it carries against MuJoCo's compiled model (``MjModel.from_xml_path``)
to 1e-12, at the start and at a random configuration; Pinocchio's parser alone reads them wrong (the defect)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from mujoco_twin import assert_same_joints, mujoco, scene_of, twins, written

# A class per attribute the parser skips: a joint's pos and axis, a geom's type, size, mass, pos and fromto, a
# partial size (its class's half-length kept), a childclass inside a body of another, class= naming a nested class.
DEFAULTS = """<mujoco model="defaults">
  <compiler angle="radian"/>
  <default>
    <joint axis="0 1 0"/>
    <geom type="capsule" size="0.02 0.1" density="500"/>
    <default class="finger">
      <joint pos="0 0 0.019" axis="1 0 0"/>
      <geom mass="0.2" pos="0 0.03 0"/>
      <default class="tip">
        <geom type="box" size="0.01 0.02 0.03" pos="0.01 0 0.05" euler="0.1 0.2 0.3"/>
      </default>
    </default>
    <default class="rod">
      <geom type="cylinder" fromto="0 0 0 0.1 0.05 0.2" size="0.015"/>
      <joint type="slide" axis="0 0.6 0.8" pos="0.01 0.02 0.03"/>
    </default>
  </default>
  <worldbody>
    <body name="base" pos="0 0 1">
      <joint name="j0"/>
      <geom size="0.05"/>
      <body name="f1" pos="0.1 0 0" childclass="finger">
        <joint name="j1"/>
        <geom/>
        <body name="f2" pos="0 0 0.2" euler="0.3 0 0">
          <joint name="j2" axis="0 0.6 0.8"/>
          <geom class="tip"/>
          <geom class="tip" quat="0.9 0.1 0 0.2"/>
        </body>
        <body name="f3" pos="0 0.1 0.2" childclass="rod">
          <joint name="j3"/>
          <geom/>
          <geom class="finger" size="0.01"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture
def defaults(tmp_path: Path) -> Path:
    return written(tmp_path, "defaults.xml", DEFAULTS)


def test_default_classes_match_mujocos_compiled_model(defaults: Path) -> None:
    scene, model = twins(defaults)
    assert_same_joints(scene, model, scene.q0)
    assert_same_joints(scene, model, np.random.default_rng(3).uniform(-1.0, 1.0, scene.model.nq))
    masses = {name: scene.model.inertias[scene.model.getJointId(name)].mass for name in ("j0", "j1", "j2", "j3")}
    expected = {name: model.body_mass[model.jnt_bodyid[model.joint(name).id]] for name in masses}
    assert masses == pytest.approx(expected, rel=1e-12)


def test_pinocchios_parser_alone_reads_the_classes_wrong(defaults: Path) -> None:
    """The defect pinstab corrects: the parser skips a class's joint pos (a finger's axis 1.9 cm off) and geom mass,
    pos and type (the two fingertip geoms 0.048 kg, MuJoCo's 0.4 kg)."""
    model = pin.buildModelFromMJCF(str(defaults))
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    theirs = mujoco.MjModel.from_xml_path(str(defaults))
    state = mujoco.MjData(theirs)
    mujoco.mj_forward(theirs, state)
    offset = np.linalg.norm(data.oMi[model.getJointId("j1")].translation - state.xanchor[theirs.joint("j1").id])
    assert offset == pytest.approx(0.019, abs=1e-12)
    assert model.inertias[model.getJointId("j2")].mass == pytest.approx(0.048, rel=1e-9)
    assert theirs.body_mass[theirs.body("f2").id] == pytest.approx(0.4, rel=1e-12)


def test_equality_solref_of_a_default_class_is_noted(tmp_path: Path) -> None:
    """``<default><equality solref>`` is an equality's soft parameter (MuJoCo's eq_solref): noted as ignored (it was
    looked for under ``<default><joint>`` and missed)."""
    path = tmp_path / "eq.xml"
    path.write_text(
        '<mujoco><default><equality solref="0.01 1"/><joint axis="1 0 0"/></default>'
        '<worldbody><body name="a"><joint name="ja"/><geom size="0.1"/><body name="b"><joint name="jb"/>'
        '<geom size="0.1"/></body></body></worldbody>'
        '<equality><joint name="pair" joint1="ja" joint2="jb"/></equality></mujoco>'
    )
    scene = scene_of(path)
    assert mujoco.MjModel.from_xml_path(str(path)).eq_solref[0].tolist() == [0.01, 1.0]
    assert any("solref/solimp/torquescale of equalities 'pair' ignored" in note for note in scene.robot.notes)
