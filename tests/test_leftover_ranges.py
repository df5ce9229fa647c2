"""Issue 34's leftovers: the actuation matrix and control bounds within MAX_MAGNITUDE (named before the rank test, which
takes the columns at unit length), the summary of a diverged servo run (the figures where the dynamics can be had),
``check`` refusing what ``run`` refuses (contacts as run takes them by default), time-stepping contacts and the joint
limits, and the friction coefficient and the directions read by one rule each (contact.coefficients,
tables.direction)."""

from __future__ import annotations

import json
import math
import textwrap
import tomllib

import numpy as np
import pinocchio as pin
import pytest
from test_catalogue import Case, run_case

from conftest import ROBOTS, bundled_with_force
from pinstab import cli, load_scene, simulate
from pinstab.actuation import read_actuation
from pinstab.errors import JointLimitsWarning, SceneError
from pinstab.grasp import GraspContact, grasp_map
from pinstab.grasp.capacity import Weight, grasp_capacity
from pinstab.scene import scene_from_dict
from pinstab.series import StateSeries
from pinstab.system import build_system
from pinstab.units import MAX_MAGNITUDE

G = 9.81
Q1, Q2 = 0.2, -0.3  # [rad] the held double pendulum's joints


def hold_scene(matrix: str, bounds: str = "") -> str:
    """The double pendulum held still at (Q1, Q2) by two servos through the actuation ``matrix`` (TOML)."""
    return textwrap.dedent(f"""\
        [robot]
        name = "double_pendulum"

        [[servos]]
        name = "arm"
        kind = "joint-relation"
        joints = {{ joint1 = 1.0 }}
        target = {{ kind = "polynomial", coefficients = [{Q1}] }}

        [[servos]]
        name = "elbow"
        kind = "joint-relation"
        joints = {{ joint2 = 1.0 }}
        target = {{ kind = "polynomial", coefficients = [{Q2}] }}

        [actuation]
        matrix = {matrix}
        names = ["shoulder", "elbow"]
        {bounds}

        [initial]
        q = {{ joint1 = {Q1}, joint2 = {Q2} }}
        """)


def gravity_torques(scene) -> np.ndarray:
    """g(q) [N m] at the held posture, by Pinocchio: what the controls carry there at rest (B u = g)."""
    return pin.computeGeneralizedGravity(scene.model, scene.model.createData(), np.array([Q1, Q2]))


def servo_case(name: str, actuation: str, phrase: str) -> Case:
    return Case(
        name, "check {scene}", "SceneError", phrase, "double-pendulum-servo", (('joints = ["joint2"]', actuation),)
    )


# -- 1. the actuation matrix and the control bounds ------------------------------------------------------------------
@pytest.mark.parametrize(
    "case",
    [
        servo_case(  # the example: refused as "its columns are dependent" (matrix_rank's tolerance 4e284)
            "matrix entry 1e300",
            "matrix = [[1e300, 0], [0, 1]]",
            "|actuation.matrix[0][0]| = 1e+300 [-] or m is outside the allowed range [0, 1e+12] [-] or m",
        ),
        servo_case("matrix entry -2e12", "matrix = [[1, 0], [0, -2e12]]", "|actuation.matrix[1][1]| = 2e+12 [-] or m"),
        servo_case(
            "lower bound -1e300",
            'joints = ["joint2"]\nlower = [-1e300]',
            "|actuation.lower[0]| = 1e+300 N m or N is outside the allowed range [0, 1e+12] N m or N",
        ),
        servo_case("upper bound 2e12", 'joints = ["joint2"]\nupper = [2e12]', "|actuation.upper[0]| = 2e+12 N m or N"),
        servo_case(
            "zero column",
            'matrix = [[1, 0], [0, 0]]\nnames = ["a", "b"]',
            "actuation.matrix: column 1 ('b') is zero: that control acts on nothing",
        ),
        servo_case("dependent columns", "matrix = [[1, -2], [0.5, -1]]", "actuation.matrix: its columns are dependent"),
    ],
    ids=lambda case: case.name,
)
def test_actuation_beyond_its_range_is_named(case, tmp_path, capsys):
    code, error, err = run_case(case, tmp_path, capsys)
    assert (code, error) == (2, "SceneError") and case.phrase in err and "Traceback" not in err, err
    if "dependent" not in case.name:
        assert "dependent" not in err


def test_independent_columns_of_any_scale_are_independent():
    """Columns of 1e12 and 1e-12 (the units of two controls) act in independent directions: accepted; matrix_rank on
    the raw matrix (tolerance 2 eps 1e12 = 4.4e-4) counted them dependent."""
    model = load_scene("double-pendulum-servo").model
    actuation = read_actuation({"matrix": [[MAX_MAGNITUDE, 0.0], [0.0, 1.0 / MAX_MAGNITUDE]]}, model)
    assert np.linalg.matrix_rank(actuation.matrix) == 1  # what the old test saw
    assert actuation.names == ("u0", "u1")


def test_actuation_at_the_ceiling_holds_the_pendulum(tmp_path):
    """B = 1e12 I with bounds +-1e12 N m (the range's ends): the servos hold the pendulum at rest with u = g(q) / 1e12,
    g by Pinocchio (1e-9 relative), the joints where they started."""
    path = tmp_path / "hold.toml"
    path.write_text(hold_scene("[[1e12, 0], [0, 1e12]]", "lower = [-1e12, -1e12]\nupper = [1e12, 1e12]"))
    scene = load_scene(path)
    trajectory = simulate(scene, duration=0.01)
    expected = gravity_torques(scene) / MAX_MAGNITUDE
    np.testing.assert_allclose(trajectory.servo_figures["controls"], np.tile(expected, (11, 1)), rtol=1e-9)
    np.testing.assert_allclose(trajectory.q, np.tile([Q1, Q2], (11, 1)), atol=1e-12)


# -- 2. the summary of a diverged servo run --------------------------------------------------------------------------
def test_a_servo_start_whose_dynamics_overflow_is_refused_before_any_step():
    """double-pendulum-servo from 1e160 rad/s: the Coriolis terms overflowed, the run diverged at its first step
    from a start where the dynamics are not finite, and its summary raised DivergenceError again. Such a start is
    refused now (v0 within MAX_RATE, as initial.v), naming the joint; the summary's rule for samples without
    dynamics (pinstab.series.NO_DYNAMICS) is checked on the series below."""
    scene = load_scene("double-pendulum-servo")
    with pytest.raises(SceneError, match=r"v0\.joint1: 1e\+160 is outside \[-1e\+06, 1e\+06\] rad/s"):
        simulate(scene, duration=0.01, v0=np.array([1e160, 0.0]))


def test_servo_figures_are_nan_only_where_the_dynamics_cannot_be_had(tmp_path):
    """Two samples of the held pendulum: at rest, controls g(q) (Pinocchio, 1e-9 relative) and no servo error; at
    1e160 rad/s (finite, its dynamics not), NaN: the figures up to the last sample that has them."""
    path = tmp_path / "hold.toml"
    path.write_text(hold_scene("[[1, 0], [0, 1]]"))
    scene = load_scene(path)
    system = build_system(scene)
    system.bind(1e-3, "rk4", scene.q0)
    t, q = np.array([0.0, 1e-3]), np.tile([Q1, Q2], (2, 1))
    v = np.array([[0.0, 0.0], [1e160, 0.0]])
    figures = StateSeries(system).servo_figures(t, q, v)
    np.testing.assert_allclose(figures["controls"][0], gravity_torques(scene), rtol=1e-9)
    assert figures["servo_error"][0] == 0.0
    assert np.isnan(figures["controls"][1]).all() and np.isnan(figures["servo_error"][1])


# -- 3. check refuses what run refuses -------------------------------------------------------------------------------
BOX_PUSH = (ROBOTS / "box-push.toml").read_text().replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
CORNER = "offset_a = [0.1, 0.05, -0.025]"


def cli_run(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main([*argv, *(["--quiet"] if argv[0] == "run" else [])])
    out, err = capsys.readouterr()
    return code, out, err


def test_check_takes_a_corner_a_hair_inside_the_table_as_run_does(tmp_path, capsys):
    """A box-push corner 1e-5 m inside the table (within MAX_PENETRATION): run starts it as given (event-driven
    contacts); check assembled the four contacts as held rows and failed (assembly failed: residual 2.5e-6 m). Both
    accept it now, check at the start as given (no assembly iterations); 1 m inside both refuse, with one message."""
    scene = tmp_path / "push.toml"
    scene.write_text(BOX_PUSH.replace(CORNER, "offset_a = [0.1, 0.05, -0.02501]", 1))
    code, out, err = cli_run(capsys, "check", str(scene), "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["assembly_iterations"] == 0 and report["assembly_residual"] == 0.0
    assert cli_run(capsys, "run", str(scene), "--duration", "0.01")[0] == 0
    scene.write_text(BOX_PUSH.replace(CORNER, "offset_a = [0.1, 0.05, -1.025]", 1))
    messages = set()
    for command in ("check", "run"):
        code, _, err = cli_run(capsys, command, str(scene))
        assert code == 2 and "Traceback" not in err, err
        messages.add(err.split(": error: ", 1)[1])
    (message,) = messages
    assert "contact 'front-left'" in message


# -- 4. time-stepping contacts and the joint limits ------------------------------------------------------------------
SLIDER = '''\
gravity = [0.0, 0.0, -9.81]

[robot]
urdf_text = """<robot name="slider"><link name="base"/><link name="carriage"/>
  <link name="block"><inertial><origin xyz="0 0 0"/><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="slide" type="prismatic"><parent link="base"/><child link="carriage"/><axis xyz="1 0 0"/>
    <limit lower="-10" upper="10" effort="100" velocity="100"/></joint>
  <joint name="lift" type="prismatic"><parent link="carriage"/><child link="block"/><axis xyz="0 0 1"/>
    <limit lower="0.5" upper="2.0" effort="100" velocity="100"/></joint>
</robot>"""

[[contacts]]
name = "floor"
kind = "plane-contact"
frame_a = "block"

[initial]
q = { lift = LIFT }
'''
LOWER = 0.5  # [m] lift's lower limit


def test_stepping_refuses_a_start_outside_the_limits_as_run_and_check_do(tmp_path, capsys):
    """A block on a lift 0.4 m high, below its lower limit 0.5 m, above the floor: run (event-driven contacts, the
    default), run --contacts stepping (which ran) and check exit 2 with the same message."""
    scene = tmp_path / "slider.toml"
    scene.write_text(SLIDER.replace("LIFT", "0.4"))
    messages = set()
    for argv in (["run"], ["run", "--contacts", "stepping"], ["run", "--contacts", "event"], ["check"]):
        code, _, err = cli_run(capsys, argv[0], str(scene), *argv[1:])
        assert code == 2 and "Traceback" not in err, (argv, err)
        messages.add(err.split(": error: ", 1)[1])
    (message,) = messages
    assert message.startswith("scene slider: the start is outside the joint limits: lift = 0.4 beyond its lower")


def test_stepping_says_when_it_leaves_the_limits_it_does_not_hold(tmp_path):
    """Dropped from 1 m, the block reaches the lift's lower limit 0.5 m at sqrt(2 * 0.5 / g) = 0.319 s: time-stepping
    contacts, which do not hold the limits, warn then (within two steps); event-driven contacts hold the limit from
    there (0.4 - 0.319 s)."""
    path = tmp_path / "slider.toml"
    path.write_text(SLIDER.replace("LIFT", "1.0"))
    scene = load_scene(path)
    reached = math.sqrt(2 * (1.0 - LOWER) / G)
    with pytest.warns(JointLimitsWarning, match="lift lower left at t = 0.3") as record:
        stepped = simulate(scene, duration=0.4, contacts="stepping")
    (warning,) = [w for w in record if issubclass(w.category, JointLimitsWarning)]
    left = float(str(warning.message).split("left at t = ")[1].split(" s")[0])
    assert abs(left - reached) <= 2e-3
    assert "time-stepping contacts do not hold" in str(warning.message)
    assert stepped.q[:, 1].min() < LOWER - 0.1
    event = simulate(scene, duration=0.4)  # the default: event-driven contacts
    assert event.info.contact_treatment["treatment"] == "event"
    assert event.q[:, 1].min() >= LOWER - 1e-9  # held to the event path's drift
    assert event.info.limits_active_s["lift lower"] == pytest.approx(0.4 - reached, abs=1e-6)


# -- 5. friction coefficients and directions, one rule each ----------------------------------------------------------
def pinch(mu: float) -> list[GraspContact]:
    """Two point contacts at -+5 cm on x, normals into the block, gravity along -z (tangent)."""
    left = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    right = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])
    return [
        GraspContact("left", "point-friction", np.array([-0.05, 0.0, 0.0]), left, mu),
        GraspContact("right", "point-friction", np.array([0.05, 0.0, 0.0]), right, mu),
    ]


@pytest.mark.parametrize("mu", [1e200, 10.5, -0.1, math.nan, True, "0.5"])
def test_a_grasp_contacts_mu_is_in_the_friction_range(mu):
    with pytest.raises(SceneError, match=r"contact 'left'\.mu must be a number in \[0, 10\] \[-\], got"):
        pinch(mu)


def test_a_pinch_at_the_friction_ceiling_needs_m_g_over_2_mu():
    """mu = 10 (MAX_FRICTION): a 1 kg block needs the closed-form squeeze m g / (2 mu) = 0.49 N (1e-9 relative)."""
    contacts = pinch(10.0)
    weight = Weight(1.0, np.zeros(3), np.array([0.0, 0.0, -G]), np.eye(3))
    capacity = grasp_capacity(grasp_map(contacts), contacts, weight, 3.0, {})
    assert capacity.squeeze_needed == pytest.approx(G / 20.0, rel=1e-9)


UNIT_SPRING = '<inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>'


def spring_axis(axis: list[float]) -> np.ndarray:
    """The unit axis of a frame-form joint-spring read from ``axis``."""
    urdf = f"""<robot name='r'><link name='base'/><link name='a'>{UNIT_SPRING}</link><link name='b'>{UNIT_SPRING}</link>
      <joint name='j1' type='revolute'><parent link='base'/><child link='a'/><axis xyz='0 0 1'/>
        <limit lower='-3' upper='3' effort='1' velocity='1'/></joint>
      <joint name='j2' type='floating'><parent link='a'/><child link='b'/></joint></robot>"""
    entry = {"name": "s", "kind": "joint-spring", "frame_a": "b", "frame_b": "a", "motion": "revolute", "axis": axis}
    (spring,) = scene_from_dict({"robot": {"urdf_text": urdf}, "forces": [entry]}, name="spring").forces
    return spring.frames[3]


def disk_directions(axis: list[float], normal: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """The unit axis and plane normal of the bundled rolling disk's contact read from ``axis`` and ``normal``."""
    text = (ROBOTS / "rolling-disk.toml").read_text().replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
    text = text.replace("axis = [0.0, 1.0, 0.0]", f"axis = {axis}").replace(
        "normal = [0.0, 0.0, 1.0]", f"normal = {normal}"
    )
    (contact,) = scene_from_dict(tomllib.loads(text), name="disk").constraints
    return contact.axis, contact.normal


@pytest.mark.parametrize("scale", [1e-300, 1e300])
def test_directions_of_any_scale_read_as_their_unit_vector(scale):
    """The rolling disk's axis and normal, a joint spring's axis and a grasp control's turning axis, given at 1e-300
    (refused as zero) or 1e300 (the norm of (1e300, 0, 1e300) overflowed: a zero axis, no turn at all), read as
    the unit vector of the same direction (1e-15)."""
    diagonal = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)
    axis, normal = disk_directions([0.0, scale, 0.0], [0.0, 0.0, scale])
    np.testing.assert_allclose(axis, [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(normal, [0.0, 0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(spring_axis([scale, 0.0, scale]), diagonal, atol=1e-15)
    (control,) = bundled_with_force("allegro-lift", axis=[scale, 0.0, scale]).forces
    np.testing.assert_allclose(control.path.axis, diagonal, atol=1e-15)


def test_a_zero_direction_is_named():
    with pytest.raises(SceneError, match=r"contact 'floor'\.axis must be a non-zero vector \(a direction\)"):
        disk_directions([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    with pytest.raises(SceneError, match=r"force 's'\.axis must be a non-zero vector \(a direction\)"):
        spring_axis([0.0, 0.0, 0.0])
