"""Scene files: bundled scenes load, bad input raises SceneError naming the item and the alternatives."""

from __future__ import annotations

import re

import numpy as np
import pytest

from conftest import ROBOTS, fourbar_dict
from pinstab import SceneError, load_scene
from pinstab.scene import scene_from_dict


@pytest.mark.parametrize(
    ("changes", "pattern"),
    [
        (
            {"robto": {}},
            r"unknown key 'robto'; valid keys: actuation, assembly, closures, contacts, description, forces, "
            r"generator, gravity, initial, name, objects, robot, run, servos",
        ),
        ({"run": {"dt": "0 ms"}}, r"run.dt must be a positive time step"),
        ({"run": {"dt": "1 m"}}, r"run.dt: unit 'm' is not a unit of time"),
        ({"run": {"step": 1e-3}}, r"unknown key 'step'; valid keys: contacts, dt"),
        ({"robot": {"urdf": "missing.urdf"}}, r"robot.urdf: file .*missing.urdf does not exist"),
        (
            {"robot": {"name": "no-such-robot"}},
            r"unknown example-robot-data robot 'no-such-robot'; valid names: .*panda",
        ),
        ({"initial": {"q": {"elbow": 1.0}}}, r"initial.q: unknown joint 'elbow'; valid joints: coupler, crank, rocker"),
        (
            {"initial": {"q": {"crank": "30 mm"}}},
            r"initial.q.crank: unit 'mm' is not a unit of angle; valid units: deg, rad",
        ),
        ({"initial": {"q": {"crank": [1, 2]}}}, r"initial.q.crank: expected a number"),
        ({"gravity": [0, -9.81]}, r"gravity must be a list of 3 numbers"),
        (
            {"closures": [{"kind": "hinge", "frame_a": "coupler"}]},
            r"kind 'hinge' is not a constraint kind; valid kinds: disk-touch, frame-orientation, frame-path, "
            r"frame-pose, geometry, grasp-contact, joint-relation, planar-point, plane-contact, point, prismatic, "
            r"revolute, rolling-contact, rolling-disk, weld",
        ),
        (
            {"closures": [{"kind": "point", "frame_a": "cupler"}]},
            r"unknown frame 'cupler'; valid frames: world, .*coupler",
        ),
        (
            {"closures": [{"kind": "planar-point", "frame_a": "coupler", "plane": "xw"}]},
            r"'plane' must be one of xy, xz, yz",
        ),
        (
            {"closures": [{"kind": "point", "frame_a": "coupler", "offset_a": [1, 2]}]},
            r"offset_a must be a list of 3 numbers",
        ),
        (
            {"forces": [{"kind": "motor"}]},
            r"kind 'motor' is not a force kind; valid kinds: external-force, grasp-control, grasp-hold, "
            r"joint-actuator, joint-friction, joint-spring, joint-torque, spring-damper",
        ),
        (
            {"forces": [{"kind": "joint-torque", "joint": "crank", "torque": "2 N"}]},
            r"unit 'N' is not a unit of torque",
        ),
        ({"forces": [{"kind": "spring-damper", "frame_a": "crank", "stiffness": -1.0}]}, r"stiffness must be >= 0"),
        (
            {"forces": [{"kind": "joint-torque", "joint": "crank", "table": [[1.0, 0.0], [0.5, 1.0]]}]},
            r"times must be strictly increasing",
        ),
    ],
)
def test_bad_scene_input_names_the_item(changes, pattern):
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(fourbar_dict(**changes))


def test_unknown_scene_lists_bundled_scenes():
    """The message lists every scene file of robots/ by name, sorted."""
    bundled = ", ".join(sorted(path.stem for path in ROBOTS.glob("*.toml")))
    with pytest.raises(SceneError, match=rf"no scene named 'nope'.*Bundled scenes: {re.escape(bundled)}\."):
        load_scene("nope")


def test_units_are_converted_to_si():
    scene = scene_from_dict(fourbar_dict(initial={"q": {"crank": "90 deg"}, "v": {"crank": "180 deg/s"}}))
    assert scene.q0[0] == pytest.approx(np.pi / 2, abs=1e-15)
    assert scene.v0[0] == pytest.approx(np.pi, abs=1e-15)


def test_invalid_toml_is_a_scene_error(tmp_path):
    path = tmp_path / "broken.toml"
    path.write_text("robot = {urdf = \n")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(path)


def test_nfourbar_parameter_sets_the_size():
    for n in (1, 3):
        scene = load_scene("nfourbar", N=n)
        assert scene.model.nv == 2 * n + 1
        assert sum(c.rows for c in scene.constraints) == 2 * n
    with pytest.raises(SceneError, match="unknown parameter 'M'; valid parameters: N, link_length, link_mass"):
        load_scene("nfourbar", M=3)
    with pytest.raises(SceneError, match="N must be an integer >= 1"):
        load_scene("nfourbar", N=0)


def test_locked_joints_reduce_the_model():
    """Panda from example-robot-data with the fingers locked: 7 DOF left, locked positions kept."""
    scene = scene_from_dict(
        {
            "robot": {"name": "panda", "locked_joints": ["panda_finger_joint1", "panda_finger_joint2"]},
            "initial": {"q": {"panda_finger_joint1": 0.02, "panda_joint4": -1.5}},
        }
    )
    assert scene.full_model.nv == 9
    assert scene.model.nv == 7
    assert scene.locked_joints == {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.0}
    assert scene.q0[scene.model.joints[scene.model.getJointId("panda_joint4")].idx_q] == -1.5


def test_repeated_names_are_refused():
    loop = fourbar_dict()["closures"][0]
    with pytest.raises(SceneError, match="repeated: loop"):
        scene_from_dict(fourbar_dict(closures=[loop, dict(loop)]))


def test_the_scene_time_step_is_the_default_of_simulate_and_the_cli(capsys):
    """``[run] dt`` sets the step of simulate() and of ``pinstab run`` when none is given; a given one wins."""
    import json

    from pinstab import simulate
    from pinstab.cli import main

    data = fourbar_dict()
    data["run"] = {"dt": "2 ms"}
    scene = scene_from_dict(data, base_dir=ROBOTS)
    assert scene.step == pytest.approx(2e-3, rel=1e-15)
    assert simulate(scene, duration=0.01).info.dt == pytest.approx(2e-3, rel=1e-15)
    assert simulate(scene, dt=1e-3, duration=0.01).info.dt == pytest.approx(1e-3, rel=1e-15)
    assert main(["run", "cassie-legs", "--duration", "0.002", "--json", "--quiet"]) == 0
    assert json.loads(capsys.readouterr().out)["dt"] == pytest.approx(5e-4, rel=1e-15)
