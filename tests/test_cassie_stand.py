"""``cassie-stand`` (issue 36): the full Cassie (16 loop closures) standing on level ground, its feet the SDF's
collision cylinders lying on their sides (contacts found from geometry), its 10 motors held by a PD posture
(``joint-spring`` with ``joints = [...]``). Checked against the closures' own residuals, the feet's world positions,
Newton's law for the whole robot at rest (the contact forces carry m g) and each contact's cone; and the list form
of ``joint-spring`` against the same springs written one by one."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from pinstab.contact.modes import Mode
from pinstab.errors import SceneError
from pinstab.kinematics import Kinematics
from pinstab.readers.base import robot_geometry
from pinstab.scene import load_scene, scene_from_dict
from pinstab.simulate import default_contacts, simulate
from pinstab.simulate.contacts import contact_system
from pinstab.solvers.contact_modes import ModeDynamics

DURATION = 1.0  # [s] of the 10 s scene (the CLI's 10 s figures are in the report)
FEET = ("left-foot_0", "right-foot_0")
MU = 0.8


@pytest.fixture(scope="module")
def stand():
    scene = load_scene("cassie-stand")
    return scene, simulate(scene, contacts="event", duration=DURATION, progress=False)


def feet_ends(scene, q: np.ndarray) -> np.ndarray:
    """The world positions [m] (4, 3) of the foot cylinders' end-cap centres, material points of the feet (from the
    collision geometry, not from the contacts)."""
    model = scene.model
    geometry = robot_geometry(scene.robot, model, {}, pin.GeometryType.COLLISION)
    data, placements = model.createData(), pin.GeometryData(geometry)
    pin.updateGeometryPlacements(model, data, geometry, placements, q)
    ends = []
    for name in FEET:
        index = geometry.getGeometryId(name)
        half = geometry.geometryObjects[index].geometry.halfLength
        ends += [placements.oMg[index].act(np.array([0.0, 0.0, side * half])) for side in (1.0, -1.0)]
    return np.array(ends)


def test_default_is_event_driven_and_the_feet_lie_flat():
    """The scene's contacts switch by default (geometry contacts beside closures: event-driven), four of them (each
    foot's two end caps), every one touching at the start."""
    scene = load_scene("cassie-stand")
    assert default_contacts(scene) == "event"
    contacts = sorted(c.name for c in scene.constraints if "/ground" in c.name)
    assert contacts == [f"{foot}/ground[{k}]" for foot in FEET for k in (0, 1)]
    ends = feet_ends(scene, scene.q0)
    assert np.abs(ends[:, 2] - 0.0168).max() <= 1e-9  # each end cap's centre a radius above the ground


def test_loops_hold_and_feet_do_not_creep(stand):
    """Over the run: every closure's residual <= 1e-8 m (rad), each foot's end caps within 1e-8 m of where they
    started (sticking: no creep), no contact event but the four starts (every contact sticks throughout)."""
    scene, run = stand
    closures = [c for c in scene.constraints if "/ground" not in c.name]
    kin = Kinematics(scene.model)
    worst = 0.0
    for q in run.q:
        kin.update_positions(q)
        worst = max(worst, max(float(np.abs(c.residual(kin, q, 0.0)).max()) for c in closures))
    assert worst <= 1e-8
    start = feet_ends(scene, run.q[0])
    creep = max(float(np.abs(feet_ends(scene, q) - start).max()) for q in run.q)
    assert creep <= 1e-8
    events = run.info.contact_events
    assert [(e["from"], e["to"], e["t"]) for e in events] == [("separated", "sticking", 0.0)] * 4


def test_rests_on_its_weight_inside_the_cones(stand):
    """At rest: base speed <= 1e-6 m/s, rad/s throughout (measured 1.1e-7, from the start's 1e-8 N m of residual
    force) and <= 1e-7 at 1 s (measured 1.1e-8; 1.1e-9 at 10 s: its slowest mode decays in about 6 s). The contact
    forces the modes' solve gives at the end sum to the robot's weight m g (1e-6 relative: Newton's law for the whole
    robot, whatever the solver), with no net horizontal force (1e-6 m g); each pushes (f_n > 0) and lies inside its
    cone (|f_t| < mu f_n)."""
    scene, run = stand
    assert np.abs(run.v[:, :6]).max() <= 1e-6
    assert np.abs(run.v[-1, :6]).max() <= 1e-7
    q, v = run.q[-1], run.v[-1]
    geometries, system, q, v, _ = contact_system(scene, q, v, closures=True)
    dynamics = ModeDynamics(system.model, geometries)
    dynamics.modes = [Mode.STICKING] * len(geometries)
    solution = dynamics.solve(q, v, float(run.t[-1]))
    world = np.array([g.basis.T @ f for g, f in zip(geometries, solution.forces, strict=True)])  # (n, t1, t2) -> xyz
    weight = pin.computeTotalMass(scene.model) * 9.81
    assert abs(world[:, 2].sum() - weight) <= 1e-6 * weight
    assert np.abs(world[:, :2].sum(axis=0)).max() <= 1e-6 * weight
    normal, tangential = solution.forces[:, 0], np.linalg.norm(solution.forces[:, 1:], axis=1)
    assert (normal > 0.0).all()
    assert (tangential < MU * normal).all()


POSTURE = {
    "robot": {"name": "cassie", "ignore_limits": ["left-foot-op", "left-tarsus-crank-joint"]},
    "initial": {"q": {"left-knee-op": -0.2}},
}


def posture_scene(**entry):
    return scene_from_dict(POSTURE | {"forces": [{"name": "posture", "kind": "joint-spring"} | entry]})


def test_joint_list_is_the_springs_one_by_one():
    """``joints = [...]`` gives one spring per joint, named ``posture/<joint>``, each the force of the same spring
    written alone (to the last bit); ``reference`` a table by joint, ``"start"`` its initial position."""
    joints = ["left-knee-op", "left-pitch-op", "right-knee-op"]
    listed = posture_scene(joints=joints, stiffness=300.0, damping=2.0, reference={"left-pitch-op": 0.1})
    mine = [f for f in listed.forces if f.name.startswith("posture/")]
    assert [f.name for f in mine] == [f"posture/{j}" for j in joints]
    assert [f.reference for f in mine] == [-0.2, 0.1, 0.0]  # the left knee's start, the table's, the right's start
    kin = Kinematics(listed.model)
    q = listed.q0.copy()
    q[7:] += 0.01 * np.arange(q.size - 7)
    v = np.linspace(-1.0, 1.0, listed.model.nv)
    kin.update(q, v)
    for element, joint, reference in zip(mine, joints, [-0.2, 0.1, 0.0], strict=True):
        alone = posture_scene(joint=joint, stiffness=300.0, damping=2.0, reference=reference).forces[-1]
        assert np.array_equal(element.generalized_force(kin, v, 0.0), alone.generalized_force(kin, v, 0.0))


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({"joints": ["left-knee-op", "left-knee-op"]}, "more than once"),
        ({"joints": ["left-pitch-rod-joint"]}, "1-DOF joints"),
        ({"joints": []}, "non-empty list"),
        ({"joints": ["left-knee-op"], "reference": "begin"}, "'start'"),
        ({"joints": ["left-knee-op"], "reference": {"right-knee-op": 0.0}}, "unknown key 'right-knee-op'"),
        ({"joints": ["knee"]}, "knee"),
    ],
)
def test_joint_list_refuses_bad_entries(entry, message):
    with pytest.raises(SceneError, match=message):
        posture_scene(**entry)


def test_run_rtol_is_checked():
    with pytest.raises(SceneError, match="run.rtol"):
        scene_from_dict(POSTURE | {"run": {"rtol": 2.0}})
