"""Physical ranges of the contact and closure parameters (issue 34, item 1): friction and restitution
coefficients, points and offsets against the scene's size, initial penetration. A value beyond its range is a
SceneError naming the item and the range, exit 2, from ``run`` and ``check`` alike, before any work; the values
at the ends of the ranges run right."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from test_catalogue import Case, run_case

from conftest import ROBOTS
from pinstab.contact.coefficients import MAX_FRICTION
from pinstab.errors import PainleveError, SceneError
from pinstab.scene import load_scene, scene_from_dict
from pinstab.simulate.api import simulate
from pinstab.tables import MAX_REACH, SceneTables, scene_size

CORNER = "offset_a = [0.1, 0.05, -0.025]"  # box-push's first corner, on the table z = 0
FOURBAR_OFFSET = "offset_a = [0.6, 0.0, 0.0]"
CUBE = """
[[objects]]
name = "cube"
shape = "box"
size = [0.1, 0.1, 0.1]
mass = 1.0
position = [0.0, 0.0, {z}]
"""

ISSUE_CASES = [
    Case(
        "painleve-rod mu 1e200",
        "{command} painleve-rod --param mu=1e200",
        "SceneError",
        "generator painleve-rod: parameter mu must be a number in [0, 10] [-], got 1e+200",
    ),
    Case(
        "incline mu 1e9",
        "{command} incline --param mu=1e9",
        "SceneError",
        "generator incline: parameter mu must be a number in [0, 10] [-], got 1000000000.0",
    ),
    Case(
        "box-push corner 1e6 m inside the plane",
        "{command} {scene}",
        "SceneError",
        "contact 'front-left'.offset_a = [0.1, 0.05, -1e+06] m lies 1e+06 m from its frame's origin, beyond 10 "
        "times the scene's size (1 m",
        base="box-push",
        changes=((CORNER, "offset_a = [0.1, 0.05, -1e6]"),),
    ),
    Case(
        "fourbar closure offset -1e308",
        "{command} {scene}",
        "SceneError",
        "closure 'coupler-rocker'.offset_a = [-1e+308, 0, 0] m lies 1e+308 m from its frame's origin",
        changes=((FOURBAR_OFFSET, "offset_a = [-1e308, 0.0, 0.0]"),),
    ),
]

RANGE_CASES = [
    Case(
        "plane contact mu above the ceiling",
        "{command} {scene}",
        "SceneError",
        "contact 'front-left'.mu must be a number in [0, 10] [-], got 10.5: measured friction coefficients",
        base="box-push",
        changes=(("\nmu = 0.5", "\nmu = 10.5"),),
    ),
    Case(
        "fingertip mu above the ceiling",
        "{command} {scene}",
        "SceneError",
        "contact 'tip'.mu must be a number in [0, 10] [-], got 11",
        base="finger-rolling",
        changes=(("mu = 0.8", "mu = 11"),),
    ),
    Case(
        "restitution above 1",
        "{command} bouncing-ball --param restitution=1.01",
        "SceneError",
        "generator bouncing-ball: parameter restitution must be a number in [0, 1] [-], got 1.01",
    ),
    Case(
        "plane contact restitution nan",
        "{command} {scene}",
        "SceneError",
        "contact 'front-left'.restitution must be a number in [0, 1] [-], got nan",
        base="box-push",
        changes=(("\nmu = 0.5", "\nmu = 0.5\nrestitution = nan"),),
    ),
    Case(
        "plane point far away",
        "{command} {scene}",
        "SceneError",
        "contact 'front-left'.point = [0, 0, -100] m lies 100 m from the scene's bodies",
        base="box-push",
        changes=(("\nmu = 0.5", "\nmu = 0.5\npoint = [0.0, 0.0, -100.0]"),),
    ),
    Case(
        "corner 0.2 mm inside the plane",
        "{command} {scene}",
        "SceneError",
        "contact 'front-left': the contact point starts 0.0002 m inside its plane, deeper than 0.0001 times the "
        "scene's size (1 m)",
        base="box-push",
        changes=((CORNER, "offset_a = [0.1, 0.05, -0.0252]"),),
    ),
    Case(
        "world closure point far away",
        "{command} {scene}",
        "SceneError",
        "closure 'coupler-rocker'.offset_b = [0, 0, 1e+09] m",
        changes=(('frame_b = "rocker"\noffset_b = [0.5, 0.0, 0.0]', "offset_b = [0.0, 0.0, 1e9]"),),
    ),
    Case(
        "closure angle beyond the coordinates",
        "{command} {scene}",
        "SceneError",
        "closure 'coupler-rocker'.rpy_a = [0.0, 0.0, 1e+300] rad is beyond 1e+06 rad",
        changes=((FOURBAR_OFFSET, FOURBAR_OFFSET + "\nrpy_a = [0.0, 0.0, 1e300]"),),
    ),
    Case(
        "object far away",
        "{command} {scene}",
        "SceneError",
        "object 'cube'.position = [0.0, 0.0, 1e+300] m is beyond 1e+06 m",
        base="box-push",
        changes=(("[[forces]]", CUBE.format(z="1e300") + "\n[[forces]]"),),
    ),
]


class Captured:
    """capfd as run_case reads it, keeping stdout too (LAPACK writes its complaints to the C stdout)."""

    def __init__(self, capfd) -> None:
        self.capfd, self.out = capfd, ""

    def readouterr(self):
        captured = self.capfd.readouterr()
        self.out = captured.out
        return captured


@pytest.mark.parametrize("command", ["run", "check"])
@pytest.mark.parametrize("case", ISSUE_CASES + RANGE_CASES, ids=[c.name for c in ISSUE_CASES + RANGE_CASES])
def test_out_of_range_is_refused_by_name_before_any_work(case, command, tmp_path, capfd):
    save = tmp_path / "r.npz"
    argv = case.argv.replace("{command}", command) + (f" --save {save}" if command == "run" else "")
    captured = Captured(capfd)
    code, error, err = run_case(Case(**{**case.__dict__, "argv": argv}), tmp_path, captured)
    assert (code, error) == (2, "SceneError"), err
    assert case.phrase in err and "Traceback" not in err
    assert captured.out == "" and "DLASCL" not in err  # nothing on stdout: no LAPACK complaint, no result
    assert not save.exists()


def test_contact_at_the_penetration_tolerance_loads_and_rests(tmp_path):
    """A corner 0.09 mm inside the table (within 1e-4 of the 1 m scene size) loads; the pushed box stays put."""
    text = (ROBOTS / "box-push.toml").read_text().replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
    scene_file = tmp_path / "shallow.toml"
    scene_file.write_text(text.replace(CORNER, "offset_a = [0.1, 0.05, -0.02509]"))
    run = simulate(load_scene(scene_file), contacts="event", duration=0.2)
    assert np.abs(np.asarray(run.q)[:, :3] - run.q[0][:3]).max() < 1e-9


@pytest.mark.parametrize("contacts", ["event", "stepping", "held"])
def test_cube_on_the_incline_rests_at_the_friction_ceiling(contacts):
    """mu = MAX_FRICTION > tan(0.5): the cube stays at rest for 1 s, to 1e-9 m, whichever contact method."""
    run = simulate(load_scene("incline", mu=MAX_FRICTION), contacts=contacts, duration=1.0)
    q = np.asarray(run.q)
    assert np.all(np.isfinite(q))
    assert np.linalg.norm(q[:, :3] - q[0, :3], axis=1).max() < 1e-9


def test_painleve_rod_at_the_friction_ceiling_is_painleves_paradox():
    """Beyond mu = 4/3 no contact mode of the sliding end is consistent: event-driven contacts stop at t = 0."""
    with pytest.raises(PainleveError, match=r"at t = 0 s no contact mode of end is consistent"):
        simulate(load_scene("painleve-rod", mu=MAX_FRICTION), contacts="event", duration=1.0)


def test_painleve_rod_time_stepping_at_the_friction_ceiling_stops_the_end():
    run = simulate(load_scene("painleve-rod", mu=MAX_FRICTION), contacts="stepping", duration=1.0)
    end = pin.SE3(np.eye(3), np.array([-0.5, 0.0, 0.0]))
    heights = [(pin.XYZQUATToSE3(x) * end).translation[2] for x in np.asarray(run.q)]
    assert min(heights) > -1e-5
    assert set(run.summary()["solver_status"]) <= {"ADMM converged", "PGS converged"}  # every step's solve checked


def test_elastic_ball_bounces_back_to_its_height():
    """restitution = 1, the top of its range: the ball dropped from a 1 m gap comes back to it."""
    run = simulate(load_scene("bouncing-ball", restitution=1.0, height=1.0), contacts="event", duration=1.2)
    radius, t0 = 0.05, math.sqrt(2.0 / 9.81)  # impact at t0, apex again at 2 t0
    z = np.asarray(run.q)[:, 2] - radius
    after = np.asarray(run.t) > 1.5 * t0
    assert z.min() > -1e-9
    assert z[after].max() == pytest.approx(1.0, abs=1e-6)


def test_scene_size_is_the_diagonal_of_the_frames():
    """nfourbar N = 10: cranks 1 m apart from x = 0 to 10, 1 m tall, in the xy plane: sqrt(10^2 + 1^2)."""
    scene = load_scene("nfourbar")
    assert scene_size(scene.model, scene.q0) == pytest.approx(math.sqrt(101.0), rel=1e-12)
    small = load_scene("box-push")  # 0.2 x 0.1 x 0.05 m: the 1 m floor
    assert scene_size(small.model, small.q0) == 1.0


def test_a_point_at_the_reach_is_accepted_one_beyond_refused():
    scene = load_scene("box-push")
    tables = SceneTables(scene.model, scene.q0)
    limit = MAX_REACH * tables.size
    tables.within_reach(np.array([0.0, 0.0, limit]), "edge")
    with pytest.raises(SceneError, match=r"edge = \[0, 0, 10\] m lies 10 m from its frame's origin, beyond 10"):
        tables.within_reach(np.array([0.0, 0.0, math.nextafter(limit, math.inf)]), "edge")


@pytest.mark.parametrize("scale", [1e-300, 1.0, 1e300])
def test_contact_normal_of_any_scale_is_its_direction(scale):
    """The table's normal given as (0, 0, s): the same contact frame whether s is 1e-300, 1 or 1e300."""
    data = {
        "robot": {"urdf": "urdf/box.urdf", "free_flyer": True},
        "contacts": [
            {"name": "c", "kind": "plane-contact", "frame_a": "box", "offset_a": [0.1, 0.05, -0.025]},
        ],
        "initial": {"q": {"root_joint": [0.0, 0.0, 0.025, 0.0, 0.0, 0.0, 1.0]}},
    }
    data["contacts"][0]["normal"] = [0.0, 0.0, scale]
    contact = scene_from_dict(data, base_dir=ROBOTS).constraints[0]
    np.testing.assert_array_equal(contact.selection, [[0.0, 0.0, 1.0]])
    np.testing.assert_allclose(contact.world_placement_b.translation, [0.1, 0.05, 0.0], atol=1e-15)
