"""The SDF reader against the XML of every SDF file example-robot-data ships (counts, poses, limits, ratios),
the Cassie scenes (closure kinds, rank and mobility, drift and energy balance, recording), the joint-spring
force against finite differences of its energy, and bad input named."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from collections import Counter

import numpy as np
import pinocchio as pin
import pytest

import pinstab
from pinstab.cli import main
from pinstab.errors import SceneError
from pinstab.kinematics import Kinematics
from pinstab.model import ConstrainedModel
from pinstab.readers import example_robot_data_dir, example_robot_names, read_robot
from pinstab.readers.sdf import read_sdf_file
from pinstab.scene import scene_from_dict

SDF_FILES = sorted(example_robot_data_dir().rglob("*.sdf")) if example_robot_data_dir() else []
STEP = 1e-6


def _xml(path):
    model = ET.parse(path).getroot().find("model")
    return model.findall("link"), model.findall("joint")


def _xml_loops(joints) -> list[str]:
    """Joints whose child already has a parent in document order, and gearboxes (independent of the reader)."""
    parented, loops = set(), []
    for joint in joints:
        child = joint.findtext("child").strip()
        if joint.get("type") == "gearbox" or child in parented:
            loops.append(joint.get("name"))
        parented.add(child)
    return loops


def _pose(element) -> pin.SE3:
    values = np.array([float(x) for x in element.findtext("pose", "0 0 0 0 0 0").split()])
    return pin.SE3(pin.rpy.rpyToMatrix(values[3:]), values[:3])


def test_the_sdf_files_are_found():
    assert {path.name for path in SDF_FILES} >= {
        "cassie.sdf",
        "cassie_v2.sdf",
        "cassie_reduced.sdf",
        "cassie_simple.sdf",
        "cassie_wo_gearbox_spring.sdf",
    }
    assert example_robot_names()["cassie"].name == "cassie.sdf"


@pytest.mark.parametrize("path", SDF_FILES, ids=lambda path: path.name)
def test_every_shipped_sdf_is_read_with_its_links_joints_and_loops(path):
    links, joints = _xml(path)
    source = read_sdf_file(path, free_flyer=False)
    model = source.model
    bodies = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    assert sorted(bodies) == sorted(link.get("name") for link in links)
    loops = _xml_loops(joints)
    closures = [entry["name"] for entry in source.tables.get("closures", [])]
    assert closures == loops
    tree = [j for j in joints if j.get("name") not in loops]
    moving = [j.get("name") for j in tree if j.get("type") != "fixed"]
    assert list(model.names[1:]) == [name for name in model.names[1:] if name in moving]
    assert sorted(model.names[1:]) == sorted(moving)
    # q = 0 places every link at its SDF pose (model frame), so the loops close there
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    for link in links:
        placement = data.oMf[model.getFrameId(link.get("name"), pin.FrameType.BODY)]
        expected = _pose(link)
        assert np.allclose(placement.translation, expected.translation, atol=1e-12)
        assert np.allclose(placement.rotation, expected.rotation, atol=1e-12)


def test_cassie_counts_and_closure_kinds():
    links, joints = _xml(example_robot_names()["cassie"])
    source = read_robot({"name": "cassie"}, example_robot_data_dir())
    assert (len(links), len(joints)) == (35, 50)
    kinds = Counter(entry["kind"] for entry in source.tables["closures"])
    assert kinds == {"joint-relation": 10, "prismatic": 2, "revolute": 2, "point": 2}
    assert source.model.names[1] == "root_joint" and source.model.nv == 6 + 32 + 2 * 3  # floating as the SDF says
    ratios = {j.get("name"): float(j.findtext("gearbox_ratio")) for j in joints if j.get("type") == "gearbox"}
    for entry in source.tables["closures"]:
        if entry["kind"] == "joint-relation":
            motor = entry["name"].replace("-joint", "")
            assert entry["joints"] == {f"{motor}-ip": ratios[entry["name"]], f"{motor}-op": 1.0}


def test_limits_and_springs_come_from_the_sdf():
    path = example_robot_names()["cassie"]
    _, joints = _xml(path)
    source = read_sdf_file(path)
    model = source.model
    springs = {entry.get("joint"): entry for entry in source.tables["forces"]}
    for joint in joints:
        name, limit = joint.get("name"), joint.find("axis/limit")
        if not model.existJointName(name) or joint.get("type") != "revolute":
            continue
        index = model.joints[model.getJointId(name)].idx_q
        lower, upper = model.lowerPositionLimit[index], model.upperPositionLimit[index]
        if limit is None:
            assert lower < -1e300 and upper > 1e300
        else:
            assert (lower, upper) == (float(limit.findtext("lower")), float(limit.findtext("upper")))
        stiffness = float(joint.findtext("axis/dynamics/spring_stiffness", "0"))
        damping = float(joint.findtext("axis/dynamics/damping", "0"))
        if stiffness or damping:
            assert springs[name]["name"] == f"{name}/dynamics"
            assert (springs[name].get("stiffness", 0.0), springs[name].get("damping", 0.0)) == (stiffness, damping)


@pytest.fixture(scope="module")
def cassie():
    scene = pinstab.load_scene("cassie")
    model = ConstrainedModel(scene)
    return scene, model, model.constraint_values(scene.q0, scene.v0, 0.0).jacobian


def test_check_lists_the_16_closures_with_rank_and_mobility(capsys, cassie):
    assert main(["check", "cassie", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    scene, model, jacobian = cassie
    assert {name: c["scene_kind"] for name, c in report["constraints"].items()} == {
        c.name: c.kind for c in scene.constraints
    }
    assert len(report["constraints"]) == 16 and report["assembly_residual"] < 1e-12
    # redundancy, closure by closure: each shin-spring triangle's prismatic closure and plantar ball repeat
    # what their parallel revolutes hold out of the leg's plane (3 and 1 rows); the rest is independent
    tol = 1e-9 * np.linalg.norm(jacobian, 2)
    own_rank = {name: np.linalg.matrix_rank(jacobian[rows], tol=tol) for name, rows in model.constraints.slices.items()}
    redundant = {name: rows.stop - rows.start - own_rank[name] for name, rows in model.constraints.slices.items()}
    assert {name: n for name, n in redundant.items() if n} == {
        "left-shin-spring-joint": 3,
        "right-shin-spring-joint": 3,
        "left-plantar-foot-joint": 1,
        "right-plantar-foot-joint": 1,
    }
    assert (report["rows"], report["rank"], report["redundant"]) == (36, 28, 8)
    # mobility 16: holding the pelvis (6) and the 10 motor outputs leaves nothing free
    names = scene.model.names
    held = list(range(6)) + [scene.model.joints[i].idx_v for i in range(len(names)) if names[i].endswith("-op")]
    assert len(held) == report["mobility"] == 16
    stacked = np.vstack([jacobian, np.eye(scene.model.nv)[held]])
    assert np.linalg.matrix_rank(stacked, tol=tol) == scene.model.nv


def test_cassie_legs_drift_and_energy_balance(capsys):
    """Short run (docs/guide/robots.md's is 2 s): drift <= 1e-8 m and the energy balance closed to 1e-6 relative."""
    assert main(["run", "cassie-legs", "--duration", "0.2", "--dt", "5e-4", "--json", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["solver"] == "pinocchio"
    assert summary["max_position_drift"] <= 1e-8
    assert summary["force_work"] < -1e-2  # the dampers took energy out
    assert summary["energy_balance_relative"] <= 1e-6


def test_cassie_legs_recording_embeds_the_meshes(capsys, tmp_path):
    out = tmp_path / "cassie.html"
    argv = ["record", "cassie-legs", "-o", str(out), "--duration", "0.02", "--dt", "5e-4", "--json", "--quiet"]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["size_bytes"] == out.stat().st_size > 2e6  # the STL meshes are inside
    assert "pinstab ready: cassie-legs" in out.read_text()


def test_cassie_legs_recording_opens_in_chromium(tmp_path):
    from pinstab.viz.browser import chromium, open_page
    from pinstab.viz.recording import write_recording

    if chromium() is None:
        pytest.skip("headless Chromium not installed")
    scene = pinstab.load_scene("cassie-legs")
    trajectory = pinstab.simulate(scene, dt=5e-4, duration=0.02)
    recording = write_recording(ConstrainedModel(scene), trajectory, tmp_path / "c.html", fps=100)
    page = open_page(recording.path, 0.01)
    assert page.title == "pinstab ready: cassie-legs"
    assert [line for line in page.console if "_meshfile is deprecated" not in line] == []


# -- joint-spring ---------------------------------------------------------------------------------------------


UNIT = "<inertial><mass value='1'/><inertia ixx='1' iyy='1' izz='1' ixy='0' ixz='0' iyz='0'/></inertial>"


def _spring_scene(entry: dict):
    urdf = f"""<robot name='r'><link name='base'/>
      <link name='a'>{UNIT}</link><link name='b'>{UNIT}</link>
      <joint name='j1' type='revolute'><parent link='base'/><child link='a'/><axis xyz='0 0 1'/>
        <limit lower='-3' upper='3' effort='1' velocity='1'/></joint>
      <joint name='j2' type='floating'><parent link='a'/><child link='b'/></joint></robot>"""
    return scene_from_dict({"robot": {"urdf_text": urdf}, "forces": [entry]}, name="spring")


FRAME_SPRINGS = [
    {"motion": "revolute", "axis": [0.2, 0.3, 0.9], "rpy_a": [0.1, 0.2, 0.3], "offset_b": [0.1, 0, 0]},
    {"motion": "prismatic", "axis": [1.0, 0.0, 0.2], "offset_a": [0.1, 0.2, 0.0], "rpy_b": [0.3, -0.2, 0.1]},
]


@pytest.mark.parametrize("extra", FRAME_SPRINGS, ids=lambda e: e["motion"])
def test_closure_spring_force_is_minus_the_energy_gradient_and_damps(extra):
    entry = {"name": "s", "kind": "joint-spring", "frame_a": "b", "frame_b": "a"}
    entry.update(extra, stiffness=40.0, reference=0.05, damping=3.0)
    scene = _spring_scene(entry)
    model, (spring,) = scene.model, scene.forces
    kin = Kinematics(model)
    rng = np.random.default_rng(7)
    q = pin.integrate(model, pin.neutral(model), 0.3 * rng.standard_normal(model.nv))
    v = rng.standard_normal(model.nv)
    kin.update(q, np.zeros(model.nv))
    static = spring.generalized_force(kin, np.zeros(model.nv), 0.0)
    gradient = np.zeros(model.nv)
    for j in range(model.nv):
        dq = np.zeros(model.nv)
        dq[j] = STEP
        energies = []
        for sign in (1, -1):
            kin.update(pin.integrate(model, q, sign * dq), np.zeros(model.nv))
            energies.append(spring.potential_energy(kin))
        gradient[j] = (energies[0] - energies[1]) / (2 * STEP)
    np.testing.assert_allclose(static, -gradient, atol=1e-7)
    kin.update(q, v)
    damping_force = spring.generalized_force(kin, v, 0.0) - static
    assert spring.power(kin, v, 0.0) == pytest.approx(float(damping_force @ v), rel=1e-12)
    assert spring.power(kin, v, 0.0) < 0


def test_joint_spring_on_a_joint_is_the_closed_form_law():
    scene = _spring_scene({"kind": "joint-spring", "joint": "j1", "stiffness": 5.0, "reference": 0.2, "damping": 0.5})
    model, (spring,) = scene.model, scene.forces
    kin = Kinematics(model)
    q, v = pin.neutral(model), np.zeros(model.nv)
    q[0], v[0] = 0.7, -1.5
    kin.update(q, v)
    assert spring.generalized_force(kin, v, 0.0)[0] == pytest.approx(-5.0 * 0.5 - 0.5 * -1.5, rel=1e-15)
    assert spring.potential_energy(kin) == pytest.approx(0.5 * 5.0 * 0.5**2, rel=1e-15)
    with pytest.raises(SceneError, match="j2.*6 DOF; a stiffness needs a 1-DOF joint"):
        _spring_scene({"kind": "joint-spring", "joint": "j2", "stiffness": 1.0})


# -- bad input ---------------------------------------------------------------------------------------------------

GOOD_LINK = "<link name='{}'><pose>0 0 0 0 0 0</pose><inertial><mass>1</mass></inertial></link>"


def _sdf(tmp_path, joints: str, links=("a", "b")) -> dict:
    path = tmp_path / "m.sdf"
    body = "".join(GOOD_LINK.format(name) for name in links)
    path.write_text(f"<sdf version='1.6'><model name='m'>{body}{joints}</model></sdf>")
    return {"robot": {"sdf": str(path)}}


@pytest.mark.parametrize(
    ("joints", "message"),
    [
        (
            "<joint name='j' type='revolute'><parent>a</parent><child>c</child><axis><xyz>0 0 1</xyz></axis></joint>",
            "sdf joint 'j': child link 'c' does not exist; links: a, b",
        ),
        (
            "<joint name='j' type='revolute'><parent>a</parent><child>b</child><axis><xyz>0 0 1</xyz>"
            "<limit><lower>1</lower><upper>-1</upper></limit></axis></joint>",
            "sdf joint 'j': limit lower 1.0 > upper -1.0",
        ),
        (
            "<joint name='j' type='universal'><parent>a</parent><child>b</child></joint>",
            "sdf joint 'j': type 'universal' is not supported; supported types: ball, continuous",
        ),
        ("", "links b are not connected to the root link 'a'"),
    ],
)
def test_bad_sdf_is_named(tmp_path, joints, message):
    with pytest.raises(SceneError, match=message):
        scene_from_dict(_sdf(tmp_path, joints), name="bad")


def test_missing_and_malformed_files_are_named(tmp_path):
    with pytest.raises(SceneError, match="robot.sdf: file .*nothing.sdf does not exist"):
        scene_from_dict({"robot": {"sdf": str(tmp_path / "nothing.sdf")}}, name="bad")
    broken = tmp_path / "broken.sdf"
    broken.write_text("<sdf><model name='m'><link name='a'></model>")
    with pytest.raises(SceneError, match="broken.sdf: not a readable XML document: mismatched tag"):
        scene_from_dict({"robot": {"sdf": str(broken)}}, name="bad")


def test_a_missing_mesh_is_named(tmp_path):
    path = tmp_path / "m.sdf"
    path.write_text(
        "<sdf version='1.6'><model name='m'><link name='a'><visual name='v'><geometry><mesh>"
        "<uri>model://nowhere/x.stl</uri></mesh></geometry></visual></link></model></sdf>"
    )
    with pytest.raises(SceneError, match="sdf link 'a' visual 'v': mesh 'model://nowhere/x.stl' is not found"):
        read_sdf_file(path)


FOURBAR_LINKS = {"crank": "0 0 0 0 0 0", "coupler": "0 0.2 0 0 0 0", "rocker": "0.6 0 0 0 0 0"}
ROD = "<inertial><pose>0 0.1 0 0 0 0</pose><mass>0.5</mass><inertia><ixx>0.002</ixx><iyy>0.0001</iyy>"
ROD += "<izz>0.002</izz></inertia></inertial>"


def test_a_spring_on_a_loop_joint_acts_along_the_closures_free_turn(tmp_path):
    """A four-bar SDF whose coupler-rocker pin is a loop joint with a spring: a revolute closure and a
    joint-spring between its frames; at the SDF pose (a parallelogram) the pin's angle is zero, so the spring
    stores k ref^2 / 2, and turning the crank by d turns the pin by -d (the parallelogram keeps its angles)."""
    links = "".join(f"<link name='{n}'><pose>{p}</pose>{ROD}</link>" for n, p in FOURBAR_LINKS.items())
    pins = [("crank-pin", "world", "crank", ""), ("coupler-pin", "crank", "coupler", "")]
    pins += [("rocker-pin", "world", "rocker", ""), ("loop-pin", "rocker", "coupler", "<pose>0.6 0 0 0 0 0</pose>")]
    joints = "".join(
        f"<joint name='{n}' type='revolute'><parent>{p}</parent><child>{c}</child>{pose}<axis><xyz>0 0 1</xyz>"
        + (
            "<dynamics><spring_stiffness>3</spring_stiffness><spring_reference>0.1</spring_reference></dynamics>"
            if n == "loop-pin"
            else ""
        )
        + "</axis></joint>"
        for n, p, c, pose in pins
    )
    path = tmp_path / "fourbar.sdf"
    path.write_text(f"<sdf version='1.6'><model name='fourbar'>{links}{joints}</model></sdf>")
    scene = scene_from_dict({"robot": {"sdf": str(path)}, "gravity": [0.0, 0.0, 0.0]}, name="sdf-fourbar")
    assert [(c.name, c.kind) for c in scene.constraints] == [("loop-pin", "revolute")]
    (spring,) = scene.forces
    assert spring.name == "loop-pin/dynamics" and scene.model.nq == 3
    kin = Kinematics(scene.model)
    q = np.array([0.2, -0.2, 0.2])  # crank and rocker turned alike, coupler back: still a parallelogram
    kin.update(q, np.zeros(3))
    assert np.abs(scene.constraint_set.residual(kin, q, 0.0)).max() < 1e-15
    assert spring.coordinate(kin)[0] == pytest.approx(-0.2, abs=1e-15)
    assert spring.potential_energy(kin) == pytest.approx(0.5 * 3.0 * 0.3**2, rel=1e-13)


def test_no_energy_balance_where_contacts_do_work():
    """The balance counts the force elements' work only: a block sliding between two squeezing fingers (friction
    work) reports none, rather than a balance off by the friction's work; grasp contacts held as rows do no work,
    and the balance of allegro-sphere closes (measured 5.2e-10 relative over 0.5 s)."""
    sliding = pinstab.simulate(pinstab.load_scene("pinch", mu=0.1), contacts="event", duration=0.3)
    assert sliding.info.contact_events and sliding.summary()["energy_start"] is not None
    assert "energy_balance_relative" not in sliding.summary()
    held = pinstab.simulate("allegro-sphere", duration=0.1)  # grasp contacts held as rows, grasp-hold torques
    assert held.summary()["energy_balance_relative"] < 1e-8


def test_a_bad_inertia_and_copies_are_named(tmp_path):
    """A link inertia that is not positive semidefinite is a SceneError naming the link (it used to end in
    Pinocchio's raw RuntimeError); copies of an SDF robot are refused (they are made of URDF documents)."""
    path = tmp_path / "m.sdf"
    path.write_text(
        "<sdf version='1.6'><model name='m'><link name='a'><inertial><mass>1</mass><inertia><ixx>-1</ixx>"
        "<iyy>1</iyy><izz>1</izz></inertia></inertial></link></model></sdf>"
    )
    with pytest.raises(SceneError, match=r"sdf link 'a': inertia is not positive semidefinite: principal moments"):
        scene_from_dict({"robot": {"sdf": str(path)}}, name="bad")
    for robot in ({"name": "cassie"}, _sdf(tmp_path, "", links=("a",))["robot"]):
        with pytest.raises(SceneError, match="robot.copies: copies of a robot are made from a URDF .*not SDF"):
            scene_from_dict({"robot": {**robot, "copies": [{"prefix": "x_"}]}}, name="bad")
