"""The bundled hand scenes: allegro-sphere and allegro-box held without creep, hold forces against
statics, the grasp report against its two constructions, grasp loss named, the CLI's answers."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from conftest import ROBOTS
from pinstab import assemble, load_scene, simulate
from pinstab.cli import EXIT_CONTACT_FAILED, main
from pinstab.errors import GraspLostError, SceneError
from pinstab.grasp.report import analyse_scene_grasps
from pinstab.scene import scene_from_dict
from pinstab.system import build_system
from pinstab.trajectory import Trajectory

BALL_MASS, GRAVITY = 0.1, 9.81


def allegro_sphere(**force_changes) -> dict:
    """allegro-sphere's content, the push force replaced by ``force_changes['push']`` if given."""
    data = tomllib.loads((ROBOTS / "allegro-sphere.toml").read_text())
    if "push" in force_changes:
        push = force_changes["push"]
        data["forces"] = [f for f in data["forces"] if f["name"] != "push"]
        if push is not None:
            data["forces"].append({"name": "push", "kind": "external-force", "frame": "ball", "force": push})
    return data


def run_json(capsys, *argv) -> tuple[int, dict | None, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, (json.loads(out) if out.strip().startswith("{") else None), err


def test_allegro_sphere_holds_without_creep(capsys):
    """Acceptance: 2 s of allegro-sphere (0.2 N push): drift <= 1e-8 m, every contact's material points
    on ball and fingertip stay within 1e-8 m (no creep), every force inside its cone (margin > 0)."""
    code, result, err = run_json(capsys, "run", "allegro-sphere", "--duration", "2", "--json", "--quiet")
    assert code == 0, err
    assert result["max_position_drift"] <= 1e-8
    assert result["max_contact_slip"] <= 1e-8
    assert result["min_cone_margin"] > 0 and result["min_normal_force"] > 0
    assert set(result["contacts"]) == {"index", "middle", "ring", "thumb"}
    assert all(entry["max_slip"] <= 1e-8 for entry in result["contacts"].values())


def test_hold_forces_carry_the_weight_and_the_ball_stays_at_rest():
    """Without the push the hold is an equilibrium: accelerations <= 1e-9, the contact forces (rotated
    to world axes) sum to the ball's weight m g to 1e-9 N with zero net moment about its centre, and
    each presses (normal > 0) inside its cone."""
    scene = scene_from_dict(allegro_sphere(push=None), base_dir=ROBOTS)
    system = build_system(scene, "baumgarte", "dense")
    start = assemble(system.model, scene.q0, scene.v0)
    evaluation = system.dynamics(start.q, start.v, 0.0)
    assert np.abs(evaluation.acceleration).max() < 1e-9
    kin = system.model.kin
    kin.update(start.q, start.v)
    ball = kin.placement(scene.objects[0].frame).translation
    force, moment = np.zeros(3), np.zeros(3)
    for contact in scene.constraints:
        placement = kin.placement(contact.object_frame)
        world = placement.rotation @ evaluation.multipliers[system.model.constraints.slices[contact.name]]
        force += world
        moment += np.cross(placement.translation - ball, world)
        margins = contact.margins(evaluation.multipliers[system.model.constraints.slices[contact.name]])
        assert margins["normal"] > 0 and margins["friction"] > 0
    np.testing.assert_allclose(force, [0.0, 0.0, BALL_MASS * GRAVITY], rtol=0, atol=1e-9)
    np.testing.assert_allclose(moment, 0.0, atol=1e-10)


def test_grasp_report_agrees_with_the_contact_rows():
    """G^T from the contact geometry equals the object columns of the contact rows (to 1e-12); four point
    contacts: G 6 x 12 of rank 6, J_h 12 x 16 of rank 12 (manipulable), internal forces 12 - 6 = 6,
    force closure with positive quality."""
    grasp = analyse_scene_grasps(load_scene("allegro-sphere"))["ball"]
    assert grasp.row_mismatch < 1e-12
    analysis = grasp.analysis
    assert analysis.grasp_map.shape == (6, 12) and analysis.rank == 6
    assert grasp.hand_jacobian.shape == (12, 16) and grasp.hand_rank == 12 and grasp.manipulable
    assert analysis.internal_forces.shape == (12, 6)
    np.testing.assert_allclose(analysis.grasp_map @ analysis.internal_forces, 0.0, atol=1e-12)
    assert analysis.force_closure and analysis.quality > 0
    # every contact point lies on the ball's surface, its normal pointing to the centre
    for geometry in grasp.contact_geometry:
        np.testing.assert_allclose(np.linalg.norm(geometry.position), 0.035, atol=1e-9)
        np.testing.assert_allclose(geometry.rotation[:, 2], -geometry.position / 0.035, atol=1e-8)


def test_grasp_command_json(capsys):
    """Acceptance: ``pinstab grasp allegro-sphere --json`` gives ranks, force closure, internal-force
    dimension and quality, with frames and units stated."""
    code, result, err = run_json(capsys, "grasp", "allegro-sphere", "--json")
    assert code == 0, err
    ball = result["objects"]["ball"]
    assert (ball["grasp_map_rank"], ball["hand_jacobian_rank"], ball["internal_force_dimension"]) == (6, 12, 6)
    assert ball["force_closure"] is True and ball["unresisted_wrench"] is None
    assert ball["quality"] > 0 and ball["smallest_singular_value"] > 0
    assert "grasp_map" in ball["frames"] and "[N]" in ball["frames"]["quality"]
    code = main(["grasp", "allegro-sphere"])
    out = capsys.readouterr().out
    assert code == 0 and "force closure: yes" in out and "rank 6" in out


def test_allegro_box_soft_fingers_hold(capsys):
    """allegro-box (ring finger locked out: 12 hand DOF + 6), soft-finger contacts with a push and a
    twist: drift and slip <= 1e-8 m, friction and torsion margins > 0 over 0.5 s."""
    scene = load_scene("allegro-box")
    assert scene.model.nv == 18 and sorted(scene.locked_joints) == [
        "joint_10.0",
        "joint_11.0",
        "joint_8.0",
        "joint_9.0",
    ]
    assert [c.rows for c in scene.constraints] == [4, 4, 4]
    code, result, err = run_json(capsys, "run", "allegro-box", "--duration", "0.5", "--json", "--quiet")
    assert code == 0, err
    assert result["max_position_drift"] <= 1e-8 and result["max_contact_slip"] <= 1e-8
    assert result["min_cone_margin"] > 0 and result["min_torsion_margin"] > 0


def test_a_push_the_grasp_cannot_take_names_the_contact_and_time(capsys, tmp_path):
    """A 5 N push (50 times the ball's weight) makes some contact slide or pull: GraspLostError with the
    contact's name and the time; the CLI exits 5 with the message, the JSON and the --save file holding the run
    up to the last step before the loss."""
    scene = scene_from_dict(allegro_sphere(push=[0.0, "5 N", 0.0]), base_dir=ROBOTS)
    with pytest.raises(
        GraspLostError, match=r"grasp lost at t = [0-9.e-]+ s: contact '(index|middle|ring|thumb)'"
    ) as info:
        simulate(scene, duration=0.2, progress=False)
    assert info.value.contacts[0] in {"index", "middle", "ring", "thumb"} and info.value.margin < 0
    assert 0 <= info.value.time <= 0.2
    path = tmp_path / "pushed.toml"
    text = (ROBOTS / "allegro-sphere.toml").read_text().replace('"0.2 N"', '"5 N"')
    path.write_text(text)
    saved = tmp_path / "pushed.npz"
    argv = ("run", str(path), "--duration", "0.2", "--quiet", "--json", "--save", str(saved))
    code, result, err = run_json(capsys, *argv)
    assert code == EXIT_CONTACT_FAILED and "grasp lost at t =" in err and "Traceback" not in err
    assert info.value.time - 1e-3 <= result["t_end"] <= info.value.time  # the last step before the loss
    assert result["stopped"]["error"] == "GraspLostError" and "grasp lost at t =" in result["error"]
    kept = Trajectory.load(saved)
    assert kept.t[-1] == result["t_end"] and np.all(np.isfinite(kept.q))


def test_grasp_of_a_scene_without_grasp_contacts_is_refused(capsys):
    code, _, err = run_json(capsys, "grasp", "fourbar")
    assert code == 2 and "scene fourbar has no grasp contacts" in err


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        ({"object": "cube"}, r"force 'hold'.object: 'cube' is not an object; objects: ball"),
        ({"contacts": ["pinky"]}, r"'pinky' is not a grasp contact on 'ball'; contacts: index, middle, ring, thumb"),
        ({"squeeze": -1.0}, r"force 'hold'.squeeze must be >= 0"),
        ({"grip": 1.0}, r"force 'hold': unknown key 'grip'"),
    ],
)
def test_bad_hold_input_is_named(change, pattern):
    data = allegro_sphere()
    data["forces"][0].update(change)
    with pytest.raises(SceneError, match=pattern):
        scene_from_dict(data, base_dir=ROBOTS)


def test_bad_facets_are_refused(capsys):
    code, _, err = run_json(capsys, "grasp", "allegro-sphere", "--facets", "2")
    assert code == 2 and "facets must be a whole number from 3 to 32" in err


@pytest.mark.parametrize(
    ("force", "phrase", "margin"),
    [
        ([0.0, 0.0, -0.5, 0.0], "would have to pull: normal force -0.5 N < 0", -0.5),
        ([0.9, 0.0, 1.0, 0.0], "would slide: tangential force 0.9 N > mu f_n = 0.8 N", 0.8 - 0.9),
        ([0.0, 0.0, 1.0, 0.006], "would spin: moment about the normal 0.006 N m > torsion f_n = 0.005 N m", -0.001),
    ],
)
def test_a_soft_finger_force_outside_its_limits_is_named(force, phrase, margin):
    """allegro-box's soft finger (mu 0.8, torsion 5 mm), forces (fx, fy, fz, mz) in its contact frame: each
    limit has its own message and the violated margin [N or N m]; inside every limit nothing is raised."""
    contact = load_scene("allegro-box").constraints[0]
    with pytest.raises(
        GraspLostError, match=rf"grasp lost at t = 0.25 s: contact 'index' \(link_3.0_tip on box\) {phrase}"
    ) as info:
        contact.check_force(np.array(force), 0.25)
    assert info.value.margin == pytest.approx(margin, abs=1e-12) and info.value.time == 0.25
    contact.check_force(np.array([0.3, 0.3, 1.0, 0.004]), 0.25)
