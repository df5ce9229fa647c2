"""The MJCF reader where Pinocchio's MJCF parser reads a file otherwise than MuJoCo (issue 34, fuzz failures):
sections after the bodies, MuJoCo's class ``main``, a compiler or top default MuJoCo refuses, the parser's own
remaining errors quoted by file; the rules' boundaries read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from pinstab.errors import SceneError
from pinstab.readers.base import ReaderOptions
from pinstab.readers.mjcf import read_mjcf

INERTIAL = '<inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>'
ONE_BODY = '<mujoco><worldbody><body name="a"><joint name="j"/>{}</body></worldbody></mujoco>'


def read(tmp_path: Path, content: str) -> pin.Model:
    """The model pinstab's MJCF reader builds from ``content``."""
    (tmp_path / "robot.xml").write_text(content, encoding="utf-8")
    return read_mjcf({"mjcf": "robot.xml"}, ReaderOptions(tmp_path)).model


def test_compiler_after_the_bodies_applies_to_them(tmp_path: Path) -> None:
    """``<compiler angle="radian">`` after ``<worldbody>``: MuJoCo reads the body's euler in radians (a quarter
    turn about z), where Pinocchio's parser alone read it in degrees (1.57 degrees)."""
    model = read(
        tmp_path,
        f'<mujoco><worldbody><body name="a"><joint name="j"/>{INERTIAL}<body name="b" euler="0 0 {np.pi / 2}">'
        f'<joint name="k"/>{INERTIAL}</body></body></worldbody><compiler angle="radian"/></mujoco>',
    )
    quarter_turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(model.jointPlacements[model.getJointId("k")].rotation, quarter_turn, atol=1e-12)


def test_default_after_the_bodies_applies_to_them(tmp_path: Path) -> None:
    model = read(
        tmp_path,
        f'<mujoco><worldbody><body name="a"><joint name="j" class="c"/>{INERTIAL}</body></worldbody>'
        '<default><default class="c"><joint type="slide" axis="1 0 0"/></default></default></mujoco>',
    )
    assert model.joints[model.getJointId("j")].shortname() == "JointModelPX"


def test_childclass_main_inside_another_class_reads_the_top_default(tmp_path: Path) -> None:
    """A body of childclass ``main`` within one of childclass ``other``: its joint is main's hinge about z, not
    other's slide."""
    model = read(
        tmp_path,
        '<mujoco><default><joint type="hinge" axis="0 0 1"/><default class="other"><joint type="slide"/></default>'
        f'</default><worldbody><body name="a" childclass="other"><joint name="j"/>{INERTIAL}'
        f'<body name="b" childclass="main"><joint name="k"/>{INERTIAL}</body></body></worldbody></mujoco>',
    )
    assert model.joints[model.getJointId("j")].shortname() == "JointModelPZ"
    assert model.joints[model.getJointId("k")].shortname() == "JointModelRZ"


def test_class_main_without_a_default_section(tmp_path: Path) -> None:
    """MuJoCo's class ``main`` exists in every model: a joint of class main, in a file without ``<default>``, is a
    hinge about z (MuJoCo's defaults)."""
    content = f'<mujoco><worldbody><body name="a"><joint name="j" class="main"/>{INERTIAL}</body></worldbody></mujoco>'
    model = read(tmp_path, content)
    assert model.joints[model.getJointId("j")].shortname() == "JointModelRZ"


@pytest.mark.parametrize(
    ("head", "phrase"),
    [
        ('<compiler inertiafromgeom="maybe"/>', "inertiafromgeom='maybe'> is not one of true, false, auto"),
        ('<default class="base"/>', "the top <default> is class 'main' in MuJoCo, not 'base'"),
        ('<asset><hfield name="h" nrow="2" ncol="2" size="1 1 1 1"/></asset>', "hfields are not supported yet"),
    ],
)
def test_refused_naming_the_file(tmp_path: Path, head: str, phrase: str) -> None:
    with pytest.raises(SceneError) as refused:
        read(
            tmp_path, f'<mujoco>{head}<worldbody><body name="a"><joint name="j"/>{INERTIAL}</body></worldbody></mujoco>'
        )
    assert phrase in str(refused.value) and str(tmp_path / "robot.xml") in str(refused.value)
    assert "From file" not in str(refused.value)  # Pinocchio's message without its source location


def test_boundaries_of_the_rules_are_read(tmp_path: Path) -> None:
    """A free joint alone in its body, a body of inertiafromgeom="false" with its <inertial>, a worldbody of one
    body: read (7 coordinates, the body's 1 kg)."""
    model = read(
        tmp_path,
        '<mujoco><compiler inertiafromgeom="false"/><worldbody><body name="a"><freejoint name="f"/>'
        f"{INERTIAL}</body></worldbody></mujoco>",
    )
    assert model.nq == 7 and model.inertias[model.getJointId("f")].mass == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("geom", "phrase"),
    [
        ('type="sdf" size="0.1"', "type 'sdf' is not a geom type Pinocchio's MJCF parser reads"),
        ('type="" size="0.1"', "type '' is not a geom type"),
        ('type="box" size="0.1 0.2"', "a box needs 3 numbers in size, size='0.1 0.2' gives 2"),
        ('type="capsule" size="0.1"', "a capsule needs 2 numbers in size"),
        ('type="sphere"', "a sphere needs 1 numbers in size, size='' gives 0"),
        ('type="sphere" size="0.1" fromto="0 0 0 0 0 1"', "a fromto places a capsule, cylinder, box, ellipsoid"),
        ('type="capsule" size="0.1" pos="0 0 0" fromto="0 0 0 0 0 1"', "both pos and fromto given"),
        ('size="0.1" shellinertia="true"', "shellinertia is not read"),
    ],
)
def test_geom_the_parser_cannot_weigh_is_named(tmp_path: Path, geom: str, phrase: str) -> None:
    with pytest.raises(SceneError, match="geom 'g'") as refused:
        read(tmp_path, ONE_BODY.format(f'<geom name="g" {geom}/>'))
    assert phrase in str(refused.value)


@pytest.mark.parametrize(
    ("geom", "mass"),
    [
        ('type="box" size="0.1 0.2 0.3"', 1000.0 * 0.2 * 0.4 * 0.6),  # MuJoCo's density 1000 kg/m^3, half sizes
        ('type="capsule" size="0.1" fromto="0 0 0 0 0 0.4"', 1000.0 * np.pi * 0.1**2 * (0.4 + 4 / 3 * 0.1)),
    ],
)
def test_geom_with_the_sizes_it_needs_is_weighed(tmp_path: Path, geom: str, mass: float) -> None:
    model = read(tmp_path, ONE_BODY.format(f"<geom {geom}/>"))
    assert model.inertias[model.getJointId("j")].mass == pytest.approx(mass, rel=1e-12)
