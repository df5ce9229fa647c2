"""``pinstab inspect``: the listing of a scene's robot against Pinocchio's own model of the same file (names,
parents, limits, masses, inertia, collision geometry), the scene's constraints by name, every bundled scene
listed, and bad arguments refused with a message."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from conftest import ROBOTS
from pinstab.cli import main
from pinstab.readers import bundled_scenes, example_robot_urdf

UNBOUNDED = np.finfo(float).max


def listed(capsys, *argv: str) -> dict:
    assert main(["inspect", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def bound(x: float) -> float | None:
    return None if not np.isfinite(x) or abs(x) >= UNBOUNDED else float(x)


def assert_model_listed(result: dict, model: pin.Model) -> None:
    """Joints (type, parent, limits), bodies (mass, centre of mass, principal inertia) and frames of ``result`` are
    those of ``model``, built by Pinocchio from the robot file."""
    joints = result["joints"]
    assert [joint["name"] for joint in joints] == list(model.names[1:])
    for j, joint in enumerate(joints, start=1):
        jm = model.joints[j]
        assert joint["parent"] == model.names[model.parents[j]]
        assert joint["type"] == jm.shortname().removeprefix("JointModel")
        assert (joint["idx_q"], joint["idx_v"]) == (jm.idx_q, jm.idx_v)
        v = slice(jm.idx_v, jm.idx_v + jm.nv)
        assert joint["velocity_limit"] == [bound(x) for x in model.velocityLimit[v]]
        assert joint["effort_limit"] == [bound(x) for x in model.effortLimit[v]]
        lower, upper = model.lowerPositionLimit[jm.idx_q], model.upperPositionLimit[jm.idx_q]
        if jm.nq == 1 and lower < upper and (np.isfinite(lower) or np.isfinite(upper)):  # see joint_limits
            assert joint["position_limit"] == [bound(lower), bound(upper)] and joint["unlimited"] is None
        else:
            assert joint["position_limit"] is None and joint["unlimited"]
    bodies = result["bodies"]
    if model.inertias[0].mass > 0:  # the links fixed to the world, merged into the universe
        assert bodies[0]["joint"] == "universe" and bodies[0]["mass"] == pytest.approx(model.inertias[0].mass)
        bodies = bodies[1:]
    assert len(bodies) == model.njoints - 1
    for j, body in enumerate(bodies, start=1):
        inertia = model.inertias[j]
        assert body["joint"] == model.names[j] and body["mass"] == pytest.approx(inertia.mass, rel=1e-15)
        np.testing.assert_allclose(body["com"], inertia.lever, atol=1e-15)
        moments = np.linalg.eigvalsh(inertia.inertia)
        np.testing.assert_allclose(body["principal_inertia"], moments, rtol=1e-12, atol=1e-18)
    assert result["total_mass"] == pytest.approx(pin.computeTotalMass(model), rel=1e-14)
    pinocchio_frames = [
        (f.name, f.type.name, model.names[f.parentJoint], model.frames[f.parentFrame].name) for f in model.frames
    ]
    frames = [(f["name"], f["type"], f["parent_joint"], f["parent_frame"]) for f in result["frames"]]
    assert frames[: len(pinocchio_frames)] == pinocchio_frames  # the scene's own operational frames come after


def test_a_urdf_file_lists_as_pinocchio_reads_it(capsys):
    path = ROBOTS / "urdf" / "fourbar.urdf"
    result = listed(capsys, str(path))
    assert_model_listed(result, pin.buildModelFromUrdf(str(path)))
    assert result["robot_format"] == "urdf" and result["constraints"] == [] and result["nv"] == 3
    assert result["collision_geometry"]["loaded"] is False
    assert "declares no collision elements" in result["collision_geometry"]["note"]


def test_panda_anchor_lists_pinocchios_reduced_panda_its_meshes_and_its_closure(capsys):
    """The fingers locked out (as buildReducedModel leaves the arm), the real limits of the Panda (velocity, effort),
    the collision meshes Pinocchio builds from the URDF, the closure by name."""
    result = listed(capsys, "panda-anchor")
    urdf, robots = example_robot_urdf("panda")
    full = pin.buildModelFromUrdf(str(urdf))
    locked = [full.getJointId(name) for name in ("panda_finger_joint1", "panda_finger_joint2")]
    q = pin.neutral(full)
    q[[full.joints[j].idx_q for j in locked]] = 0.02
    geometry = pin.buildGeomFromUrdf(
        full, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(robots.parent.parent)]
    )
    model, geometry = pin.buildReducedModel(full, geometry, locked, q)  # the fingers' meshes move with joint 7
    assert_model_listed(result, model)
    assert result["joints"][3]["position_limit"] == pytest.approx([-3.0718, -0.0698])  # panda_joint4
    assert result["joints"][0]["effort_limit"] == [87.0] and result["joints"][6]["velocity_limit"] == [2.61]
    listed_geometry = result["collision_geometry"]["geometries"]
    assert [(g["name"], g["parent_joint"], g["parent_frame"]) for g in listed_geometry] == [
        (g.name, model.names[g.parentJoint], model.frames[g.parentFrame].name) for g in geometry.geometryObjects
    ]
    for item, g in zip(listed_geometry, geometry.geometryObjects, strict=True):  # meshes by file, primitives by shape
        assert item["shape"] == type(g.geometry).__name__
        assert item["mesh"] == (g.meshPath.rsplit("/", 1)[-1] if g.meshPath.endswith(".stl") else None)
    assert {g["shape"] for g in listed_geometry} == {"BVHModelOBBRSS", "Box"}
    assert [c["name"] for c in result["constraints"]] == ["flange-anchor"]
    assert result["locked_joints"] == {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}


def test_fourbar_mjcf_lists_pinocchios_mjcf_model_and_its_equality(capsys):
    result = listed(capsys, "fourbar-mjcf")
    assert_model_listed(result, pin.buildModelFromMJCF(str(ROBOTS / "mjcf" / "fourbar.xml")))
    assert [(c["name"], c["kind"], c["rows"]) for c in result["constraints"]] == [("coupler-rocker", "point", 3)]


def test_cassie_from_its_sdf_lists_its_loops_springs_and_primitive_geometry(capsys):
    result = listed(capsys, "cassie")
    assert result["robot_format"] == "sdf" and result["nv"] == 44 and len(result["joints"]) == 35
    assert len(result["constraints"]) == 16 and sum(c["kind"] == "joint-relation" for c in result["constraints"]) == 10
    assert {"name": "left-knee-op/dynamics", "kind": "JointSpring"} in result["forces"]
    shapes = {g["shape"] for g in result["collision_geometry"]["geometries"]}
    assert shapes == {"Sphere", "Cylinder"} and all(
        g["mesh"] is None for g in result["collision_geometry"]["geometries"]
    )


def test_every_bundled_scene_lists_as_text_and_json(capsys):
    for name in bundled_scenes():
        assert main(["inspect", name]) == 0, name
        text = capsys.readouterr().out
        result = listed(capsys, name)
        assert result["scene"] and f"joints ({len(result['joints'])})" in text, name
        assert all(c["name"] in text for c in result["constraints"]), name


@pytest.mark.parametrize(
    ("argument", "message"),
    [
        ("pyproject.toml", "unknown key"),
        ("README.md", "not a scene (.toml) nor a robot file (.urdf, .sdf, .xml, .mjcf)"),
        ("missing.urdf", "robot file missing.urdf does not exist"),
        ("nope", "Bundled scenes: allegro-box"),
    ],
)
def test_what_is_neither_a_scene_nor_a_robot_file_is_refused(capsys, argument, message):
    assert main(["inspect", argument]) == 2
    captured = capsys.readouterr()
    assert message in captured.err and "Traceback" not in captured.err and captured.out == ""
