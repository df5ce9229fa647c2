"""Grasp contact rows against finite differences (every contact model), bad grasp-contact and robot ``copies``
input named in SceneError and by the CLI (exit 2), and copies of a robot against the single robot."""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

from pinstab import SceneError
from pinstab.cli import main
from pinstab.kinematics import Kinematics
from pinstab.readers import example_robot_urdf
from pinstab.scene import Scene, scene_from_dict

FINGER_Q = {
    "finger_base_to_upper_joint": 0.2,
    "finger_upper_to_middle_joint": 0.5,
    "finger_middle_to_lower_joint": -1.2,
}
TIP = "finger_tip_link"
TIP_RADIUS = 0.0095  # [m]
BALL_RADIUS = 0.03  # [m]
GAP = 5e-4  # [m] left between fingertip and ball by initial.q (the loader closes it)
APPROACH = np.array([0.6, 0.5, -0.62])  # from the fingertip towards the ball's centre (normalized below)
ROWS = {"frictionless": 1, "point-friction": 3, "soft-finger": 4, "rigid": 6}
MODELS = tuple(ROWS)
STEP = 1e-7  # [rad, m]: central differences of the residual
RATE_STEP = 1e-6  # [s]: central differences of G v along q (+) s v
JACOBIAN_TOLERANCE = 1e-6  # relative to the largest entry of G
DRIFT_TOLERANCE = 1e-5  # relative to the largest entry of gamma0


def finger_model() -> pin.Model:
    return pin.buildModelFromUrdf(str(example_robot_urdf("finger_edu")[0]))


def ball_position() -> list[float]:
    """The ball's centre [m]: GAP beyond touching the fingertip at FINGER_Q, along APPROACH."""
    model = finger_model()
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.array(list(FINGER_Q.values())))
    centre = data.oMf[model.getFrameId(TIP)].translation
    direction = APPROACH / np.linalg.norm(APPROACH)
    return [float(x) for x in centre + (TIP_RADIUS + BALL_RADIUS + GAP) * direction]


def finger_ball(model: str = "point-friction", contact: dict[str, Any] | None = None, **ball: Any) -> dict:
    """Scene-file content: finger_edu pressing a ball (radius 30 mm, 50 g, turned so that its frame is not the
    world's) with one grasp contact ``tip`` of ``model``; ``contact`` and ``ball`` replace entries of the contact
    and the ball."""
    entry = {
        "name": "tip",
        "kind": "grasp-contact",
        "finger": TIP,
        "object": "ball",
        "model": model,
        "radius": TIP_RADIUS,
    }
    if model in ("point-friction", "soft-finger"):
        entry["mu"] = 0.8
    if model == "soft-finger":
        entry["torsion"] = 0.005
    sphere = {"name": "ball", "shape": "sphere", "radius": BALL_RADIUS, "mass": 0.05, "rpy": [0.4, -0.3, 0.9]}
    sphere["position"] = ball_position()
    return {
        "robot": {"name": "finger_edu"},
        "objects": [{**sphere, **ball}],
        "contacts": [{**entry, **(contact or {})}],
        "initial": {"q": dict(FINGER_Q)},
    }


def residual(scene: Scene, kin: Kinematics, q: np.ndarray) -> np.ndarray:
    kin.update_positions(q)
    return scene.constraints[0].residual(kin, q, 0.0)


def rows_times(scene: Scene, kin: Kinematics, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """G(q) v."""
    kin.update_jacobians(q)
    return scene.constraints[0].velocity_terms(kin, q, 0.0).jacobian @ v


def perturbed_state(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """A configuration a random step from the start (finger and ball moved: phi != 0) and a random velocity."""
    rng = np.random.default_rng(11)
    q = pin.integrate(scene.model, scene.q0, 0.05 * rng.standard_normal(scene.model.nv))
    return q, rng.standard_normal(scene.model.nv)


def point_rows_at_contact(scene: Scene, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """R_C^T (J_o - J_f) and R_C^T (a_o - a_f) of the point rows: the rows and drift as if the two points
    coincided (phi = 0), without the rotating-frame terms; ``kin`` fully updated."""
    contact = scene.constraints[0]
    rotation = kin.placement(contact.object_frame).rotation
    jacobian = rotation.T @ (kin.jacobian(contact.object_frame) - kin.jacobian(contact.finger_frame))[:3]
    drift = rotation.T @ (
        kin.drift_acceleration(contact.object_frame).linear - kin.drift_acceleration(contact.finger_frame).linear
    )
    return jacobian, drift


@pytest.mark.parametrize("model", MODELS)
def test_rows_are_the_derivative_of_the_residual(model):
    """G = d phi / dq through pin.integrate, column by column, within 1e-6 of max |G|, at a configuration where
    the points are apart (phi != 0) so that the turning contact frame's term R_C^T [d]x omega_o counts."""
    scene = scene_from_dict(finger_ball(model))
    kin = Kinematics(scene.model)
    q, v = perturbed_state(scene)
    kin.update(q, v)
    contact = scene.constraints[0]
    rows = contact.velocity_terms(kin, q, 0.0).jacobian
    assert rows.shape == (ROWS[model], scene.model.nv)
    point_rows = contact.components < 3
    coincident, _ = point_rows_at_contact(scene, kin)
    columns = []
    for k in range(scene.model.nv):
        step = np.zeros(scene.model.nv)
        step[k] = STEP
        forward = residual(scene, kin, pin.integrate(scene.model, q, step))
        backward = residual(scene, kin, pin.integrate(scene.model, q, -step))
        columns.append((forward - backward) / (2 * STEP))
    difference = np.column_stack(columns)
    tolerance = JACOBIAN_TOLERANCE * np.abs(rows).max()
    assert np.linalg.norm(residual(scene, kin, q)) > 1e-3
    assert np.abs(difference - rows).max() < tolerance
    assert np.abs(coincident[contact.components[point_rows]] - rows[point_rows]).max() > 100 * tolerance


@pytest.mark.parametrize("model", MODELS)
def test_drift_is_the_rate_of_the_rows(model):
    """gamma0 = d/dt (G v) along q(s) = q (+) s v with v held (zero acceleration), within 1e-5 of max |gamma0|,
    at phi != 0; dropping the rotating-frame terms would miss by far more."""
    scene = scene_from_dict(finger_ball(model))
    kin = Kinematics(scene.model)
    q, v = perturbed_state(scene)
    kin.update(q, v)
    contact = scene.constraints[0]
    drift = contact.drift(kin, q, v, 0.0)
    _, coincident = point_rows_at_contact(scene, kin)
    forward = rows_times(scene, kin, pin.integrate(scene.model, q, RATE_STEP * v), v)
    backward = rows_times(scene, kin, pin.integrate(scene.model, q, -RATE_STEP * v), v)
    tolerance = DRIFT_TOLERANCE * np.abs(drift).max()
    point_rows = contact.components < 3
    assert np.abs(drift).max() > 1e-2
    assert np.abs((forward - backward) / (2 * RATE_STEP) - drift).max() < tolerance
    assert np.abs(coincident[contact.components[point_rows]] - drift[point_rows]).max() > 100 * tolerance


def test_the_loader_closes_the_gap():
    """At the start the fingertip sphere touches the ball: centre distance = the radii's sum within 1e-9 m."""
    scene = scene_from_dict(finger_ball())
    data = scene.model.createData()
    pin.framesForwardKinematics(scene.model, data, scene.q0)
    distance = np.linalg.norm(data.oMf[scene.frame_id(TIP)].translation - data.oMf[scene.frame_id("ball")].translation)
    assert abs(distance - TIP_RADIUS - BALL_RADIUS) < 1e-9


# -- bad input -------------------------------------------------------------------------------------------
FAR = [1.0, 1.0, 1.0]
BAD_GRASP = [
    ({"contact": {"finger": "fingertip"}}, r"contact 'tip'\.finger: unknown frame 'fingertip'; valid frames: world"),
    (
        {"contact": {"object": "finger_lower_link"}},
        r"contact 'tip'\.object: 'finger_lower_link' is not an object of the scene; 'finger_lower_link' is a body "
        r"of the robot, not an object; objects: ball",
    ),
    ({"contact": {"mu": -0.1}}, r"contact 'tip'\.mu must be a number in \[0, 10\] \[-\], got -0\.1"),
    ({"contact": {"radius": 0.0}}, r"contact 'tip'\.radius must be > 0, got 0\.0"),
    ({"contact": {"radius": "-2 mm"}}, r"contact 'tip'\.radius must be > 0, got '-2 mm'"),
    ({"position": FAR}, r"contact 'tip': fingertip 'finger_tip_link' cannot reach object 'ball': a gap of"),
]
BAD_COPIES = [
    ("finger0_", r"robot\.copies must be a non-empty list of tables"),
    ([], r"robot\.copies must be a non-empty list of tables"),
    ([{"prefix": "a_"}, "b_"], r"robot\.copies\[1\] must be a table"),
    ([{"xyz": [0.0, 0.0, 0.0]}], r"robot\.copies\[0\]\.prefix must be a non-empty string without spaces, got None"),
    ([{"prefix": "a b"}], r"robot\.copies\[0\]\.prefix must be a non-empty string without spaces, got 'a b'"),
    (
        [{"prefix": "a_"}, {"prefix": "a_"}],
        r"robot\.copies\[1\]\.prefix: 'a_' is already the prefix of robot\.copies\[0\]",
    ),
    ([{"prefix": "a_", "rpy": [0.0, 0.0]}], r"robot\.copies\[0\]\.rpy must be a list of 3 numbers"),
    ([{"prefix": "a_", "xyz": [0.0, "1 s", 0.0]}], r"robot\.copies\[0\]\.xyz: unit 's' is not a unit of length"),
    ([{"prefix": "a_", "yaw": 1.0}], r"robot\.copies\[0\]: unknown key 'yaw'; valid keys: prefix, rpy, xyz"),
    (
        [{"prefix": "p_"}, {"prefix": "p_finger_"}],
        r"robot\.copies: the prefixes make link names collide: p_finger_base_link",
    ),
]


def copies_scene(copies: Any) -> dict:
    return {"robot": {"name": "finger_edu", "copies": copies}}


@pytest.mark.parametrize(("changes", "pattern"), BAD_GRASP)
def test_bad_grasp_contact_is_named(changes, pattern):
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(finger_ball(**changes))


@pytest.mark.parametrize(("copies", "pattern"), BAD_COPIES)
def test_bad_copies_are_named(copies, pattern):
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(copies_scene(copies))


def test_copies_of_text_that_is_not_xml_are_refused():
    with pytest.raises(SceneError, match=r"robot\.copies: the robot's URDF is not valid XML"):
        scene_from_dict({"robot": {"urdf_text": "<robot name='x'><link></robot>", "copies": [{"prefix": "a_"}]}})


def toml_value(value: Any) -> str:
    """A TOML value (inline tables and arrays) for JSON-like data."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


def toml_text(data: dict) -> str:
    """A scene file: top-level tables as [key], arrays of tables as [[key]]."""
    lines = []
    for key, value in data.items():
        entries = value if isinstance(value, list) else [value]
        for entry in entries:
            lines.append(f"[[{key}]]" if isinstance(value, list) else f"[{key}]")
            lines += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in entry.items()]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(
    ("data", "pattern"),
    [(finger_ball(**changes), pattern) for changes, pattern in BAD_GRASP]
    + [(copies_scene(copies), pattern) for copies, pattern in BAD_COPIES],
)
def test_cli_run_exits_2_naming_the_item(capsys, tmp_path, data, pattern):
    path = tmp_path / "scene.toml"
    path.write_text(toml_text(data))
    code = main(["run", str(path), "--quiet"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.startswith("pinstab run: error: ") and "Traceback" not in err
    assert re.search(pattern, err), err


# -- copies of a robot -----------------------------------------------------------------------------------
PLACEMENTS = [([0.1, -0.2, 0.05], [0.0, 0.0, 0.0]), ([-0.3, 0.25, 0.1], [0.2, -0.1, 2.0])]


def test_copies_move_like_the_robot_at_their_placements():
    """Each copy's fingertip is the single robot's, carried by the copy's placement (1e-15 m), its joint-space
    inertia block is the single robot's (1e-15), the copies do not couple, and the joint order is depth-first."""
    copies = [{"prefix": f"c{k}_", "xyz": xyz, "rpy": rpy} for k, (xyz, rpy) in enumerate(PLACEMENTS)]
    scene = scene_from_dict(copies_scene(copies))
    model, single = scene.model, finger_model()
    data, single_data = model.createData(), single.createData()
    assert model.check(data) and all(model.parents[j] < j for j in range(1, model.njoints))
    assert scene.urdf_path is None and scene.urdf_text is not None and scene.package_dirs
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.0, 1.0, model.nq)
    pin.framesForwardKinematics(model, data, q)
    mass = pin.crba(model, data, q)
    for k, (xyz, rpy) in enumerate(PLACEMENTS):
        joints = [model.getJointId(f"c{k}_{name}") for name in FINGER_Q]
        block = [model.joints[j].idx_q for j in joints]
        assert block == list(range(block[0], block[0] + 3))  # a copy's joints are consecutive
        pin.framesForwardKinematics(single, single_data, q[block])
        expected = pin.SE3(pin.rpy.rpyToMatrix(np.array(rpy)), np.array(xyz)) * single_data.oMf[single.getFrameId(TIP)]
        assert np.abs(data.oMf[model.getFrameId(f"c{k}_{TIP}")].homogeneous - expected.homogeneous).max() < 1e-15
        single_mass = pin.crba(single, single_data, q[block])
        assert np.abs(np.triu(mass[np.ix_(block, block)]) - np.triu(single_mass)).max() < 1e-15
    assert np.abs(mass[:3, 3:]).max() == 0.0


def test_copies_keep_their_meshes():
    """The composed URDF's visuals resolve through the scene's package_dirs: each copy has the robot's."""
    scene = scene_from_dict(copies_scene([{"prefix": "a_"}, {"prefix": "b_", "xyz": [0.2, 0.0, 0.0]}]))
    single_path = example_robot_urdf("finger_edu")[0]
    single = pin.buildGeomFromUrdf(
        finger_model(), str(single_path), pin.GeometryType.VISUAL, package_dirs=scene.package_dirs
    )
    composed = pin.buildGeomFromUrdfString(
        scene.model, scene.urdf_text, pin.GeometryType.VISUAL, package_dirs=scene.package_dirs
    )
    assert composed.ngeoms == 2 * single.ngeoms > 0
    assert {g.meshPath for g in composed.geometryObjects} == {g.meshPath for g in single.geometryObjects}


@pytest.mark.parametrize("model", MODELS)
def test_the_compiled_residual_is_the_points_difference_in_the_contact_frame(model):
    """phi's point rows = R_C^T (p_o - p_f) from Pinocchio's placements (1e-15 m), the slip its norm, after a
    placements-only pass as after a full one."""
    scene = scene_from_dict(finger_ball(model))
    kin = Kinematics(scene.model)
    q, _ = perturbed_state(scene)
    kin.update_positions(q)
    contact = scene.constraints[0]
    on_object = kin.placement(contact.object_frame)
    expected = on_object.rotation.T @ (on_object.translation - kin.placement(contact.finger_frame).translation)
    point_rows = contact.components < 3
    phi = contact.residual(kin, q, 0.0)
    assert np.linalg.norm(expected) > 1e-3
    assert np.abs(phi[point_rows] - expected[contact.components[point_rows]]).max() < 1e-15
    assert contact.slip(kin) == pytest.approx(np.linalg.norm(expected), abs=1e-15) or contact.model == "frictionless"
