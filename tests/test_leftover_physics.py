"""Issue 34's leftovers in the physics: a robot of one joint (nv = 1) with contacts and closures; a ceiling on the start
velocity; the robot file's effort limits as control bounds; the servo's realizability free of the controls' units."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest
from scipy.integrate import quad
from test_catalogue import Case, run_case

from conftest import ROBOTS
from pinstab import cli, load_scene, simulate
from pinstab.actuation import effort_bounds
from pinstab.errors import SceneError, ServoInfeasibleError
from pinstab.kernels import least_norm, servo_realizability
from pinstab.readers import example_robot_names, read_robot
from pinstab.units import MAX_MAGNITUDE, MAX_RATE

G = 9.81
ARM = 1.0  # [m] the pendulum's point mass (1 kg) from the hinge
INERTIA = 1e-6  # [kg m^2] its own moment about the hinge axis (about its centre)
REACH = 0.8  # [m] the contact point from the hinge
FLOOR = -0.4  # [m] the plane: the contact point touches it at 30 deg below the horizontal


def pendulum_urdf(joint: str = 'type="continuous"', limit: str = "") -> str:
    """One joint about y (positive: the arm, along x at 0, turns down), a point mass of 1 kg at ARM."""
    return textwrap.dedent(f"""\
        <robot name="pendulum">
          <link name="base"/>
          <link name="arm">
            <inertial><origin xyz="{ARM} 0 0"/><mass value="1"/>
              <inertia ixx="{INERTIA}" iyy="{INERTIA}" izz="{INERTIA}" ixy="0" ixz="0" iyz="0"/></inertial>
          </link>
          <joint name="hinge" {joint}>
            <parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>{limit}
          </joint>
        </robot>
        """)


def pendulum_scene(tmp_path, body: str, urdf: str | None = None, gravity: float = -G) -> str:
    """A scene file of the pendulum with ``body`` (TOML tables); its path."""
    (tmp_path / "pendulum.urdf").write_text(urdf or pendulum_urdf())
    path = tmp_path / "pendulum.toml"
    path.write_text(f'gravity = [0.0, 0.0, {gravity}]\n[robot]\nurdf = "pendulum.urdf"\n' + textwrap.dedent(body))
    return str(path)


def floor_contact(start: str) -> str:
    return f"""
        [[contacts]]
        name = "tip"
        kind = "plane-contact"
        frame_a = "arm"
        offset_a = [{REACH}, 0.0, 0.0]
        point = [0.0, 0.0, {FLOOR}]
        mu = 0.0

        [initial]
        q = {{ hinge = "{start}" }}
        """


def fall_time() -> float:
    """The time [s] the pendulum released level takes to turn 30 deg: energy, theta'^2 = 2 m g L sin(theta) / I,
    integrated (theta = u^2 takes the integrand's 1/sqrt singularity away)."""
    rate = 2.0 * G * ARM / (ARM**2 + INERTIA)
    time, _ = quad(lambda u: 2.0 * u / math.sqrt(rate * math.sin(u * u)), 0.0, math.sqrt(math.pi / 6), epsabs=1e-15)
    return time


# -- 1. one joint (nv = 1): Pinocchio's Jacobians come back as 1-D arrays ----------------------------------------------
RESTING_FORCE = G * ARM / REACH  # [N] the frictionless plane's force: its moment about the hinge carries the weight's


def test_a_pendulum_falls_onto_a_plane_at_its_closed_form_time_event_driven(tmp_path):
    """nv = 1 ended in 'could not broadcast (3,) into (3,1)'. The pendulum released level meets the plane at the
    closed-form time (1e-9 s), loses its kinetic energy m g L sin 30 deg there (the plane blocks its one motion) and
    rests with the normal force m g L / l of the moment balance (1e-9 relative), 30 deg down."""
    trajectory = simulate(load_scene(pendulum_scene(tmp_path, floor_contact("0 deg"))), duration=0.4, contacts="event")
    impact = next(e for e in trajectory.info.contact_events if e["cause"] == "impact")
    assert impact["t"] == pytest.approx(fall_time(), abs=1e-9)
    assert impact["work"] == pytest.approx(-G * ARM * 0.5, rel=1e-9)
    last = trajectory.info.contact_events[-1]
    np.testing.assert_allclose(last["force"], [RESTING_FORCE, 0.0, 0.0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(trajectory.q[-1], [math.cos(math.pi / 6), math.sin(math.pi / 6)], atol=1e-9)


def test_a_pendulum_falls_onto_a_plane_time_stepping(tmp_path):
    """Time-stepping contacts (dt = 1 ms): the impulse in the step (its event at the step's start) that holds the
    closed-form time, then at rest on the plane 30 deg down (to the stepping's penetration, 1e-6 rad)."""
    trajectory = simulate(
        load_scene(pendulum_scene(tmp_path, floor_contact("0 deg"))), duration=0.4, contacts="stepping"
    )
    first = next(e for e in trajectory.info.contact_events if e["to"] != "separated")
    assert first["t"] <= fall_time() < first["t"] + 1e-3
    np.testing.assert_allclose(trajectory.q[-1], [math.cos(math.pi / 6), math.sin(math.pi / 6)], atol=1e-6)
    assert np.abs(trajectory.v[-1]).max() < 1e-6


def test_a_pendulum_resting_on_a_held_plane_contact_has_the_moment_balance_force(tmp_path):
    """The API's default (contacts held as rows): at rest 30 deg down, the contact's multipliers are the normal force
    m g L / l and no tangential force (1e-9 relative), the pendulum still."""
    trajectory = simulate(load_scene(pendulum_scene(tmp_path, floor_contact("30 deg"))), contacts="held", duration=0.05)
    np.testing.assert_allclose(trajectory.multipliers[-1], [RESTING_FORCE, 0.0, 0.0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(trajectory.q[-1], [math.cos(math.pi / 6), math.sin(math.pi / 6)], atol=1e-12)


@pytest.mark.parametrize("contacts", ["event", "stepping", "held"])
def test_the_issue_example_runs_with_every_contact_mode(contacts, tmp_path, capsys):
    """`pinstab run S.toml --contacts event|stepping|held`: exit 0, no traceback (held: the start on the plane)."""
    scene = pendulum_scene(tmp_path, floor_contact("30 deg" if contacts == "held" else "0 deg"))
    code = cli.main(["run", scene, "--contacts", contacts, "--duration", "0.05", "--quiet"])
    assert code == 0 and "Traceback" not in capsys.readouterr().err


@pytest.mark.parametrize("solver", [None, "proxsuite"], ids=["native", "general"])
def test_a_point_closure_on_one_joint_carries_the_weight(solver, tmp_path):
    """A point closure holding the level pendulum's mass point where it starts (3 rows, rank 1): Pinocchio's path and
    pinstab's general path alike keep it still, the closure carrying m g upwards and nothing across (1e-9)."""
    body = f"""
        [[closures]]
        name = "hold"
        kind = "point"
        frame_a = "arm"
        offset_a = [{ARM}, 0.0, 0.0]
        offset_b = [{ARM}, 0.0, 0.0]
        """
    trajectory = simulate(load_scene(pendulum_scene(tmp_path, body)), duration=0.05, solver=solver)
    assert trajectory.info.path == ("native" if solver is None else "general")
    np.testing.assert_allclose(trajectory.multipliers[-1], [0.0, 0.0, G], atol=1e-9)
    np.testing.assert_allclose(trajectory.q[-1], [1.0, 0.0], atol=1e-12)


# -- 2. a ceiling on the start velocity --------------------------------------------------------------------------------
SERVO_START = "q = { joint1 = 0.5 }"
RATE_PHRASE = "is outside [-1e+06, 1e+06] rad/s or m/s"


@pytest.mark.parametrize(
    "case",
    [
        Case(
            f"{command} from 1e160 rad/s",
            f"{command} {{scene}}" + (" -o {tmp}/table.csv --grid dt=1e-3" if command == "sweep" else ""),
            "SceneError",
            f"initial.v.joint1: 1e+160 {RATE_PHRASE}",
            "double-pendulum-servo",
            ((SERVO_START, SERVO_START + "\nv = { joint1 = 1e160 }"),),
        )
        for command in ("run", "check", "servo", "sweep")
    ]
    + [
        Case(
            "an object's twist of -2e6 m/s",
            "run {scene}",
            "SceneError",
            f"initial.v.root_joint[1]: -2e+06 {RATE_PHRASE}",
            "incline",
            (("[generator]", "[initial]\nv = { root_joint = [0.0, -2e6, 0.0, 0.0, 0.0, 0.0] }\n\n[generator]"),),
        )
    ],
    ids=lambda case: case.name,
)
def test_a_start_velocity_beyond_its_range_is_named(case, tmp_path, capsys):
    code, error, err = run_case(case, tmp_path, capsys)
    assert (code, error) == (2, "SceneError") and case.phrase in err and "Traceback" not in err, err


def test_the_api_start_velocity_has_the_scene_range():
    with pytest.raises(SceneError, match=r"v0\.joint2: -1\.5e\+06 is outside \[-1e\+06, 1e\+06\]"):
        simulate(load_scene("double-pendulum-servo"), duration=0.01, v0=np.array([0.0, -1.5e6]))


def test_a_start_at_the_ceiling_turns_as_it_should(tmp_path):
    """The boundary: the pendulum without gravity spun at MAX_RATE keeps its rate and turns 1e4 rad in 10 ms (its
    configuration [cos, sin] of the angle to 1e-9; the kinetic energy I w^2 / 2 to 1e-12 relative)."""
    body = f"[initial]\nv = {{ hinge = {MAX_RATE} }}\n"
    trajectory = simulate(load_scene(pendulum_scene(tmp_path, body, gravity=0.0)), duration=0.01)
    angle = MAX_RATE * 0.01
    np.testing.assert_allclose(trajectory.q[-1], [math.cos(angle), math.sin(angle)], atol=1e-9)
    np.testing.assert_allclose(trajectory.v[:, 0], MAX_RATE, rtol=1e-12)
    kinetic = 0.5 * (ARM**2 + INERTIA) * MAX_RATE**2
    np.testing.assert_allclose(trajectory.energy, kinetic, rtol=1e-12)


# -- 3. the robot file's effort limits -----------------------------------------------------------------------------
HOLD_LEVEL = """
    [[servos]]
    name = "level"
    kind = "joint-relation"
    joints = { hinge = 1.0 }
    target = { kind = "polynomial", coefficients = [0.0] }

    [actuation]
    joints = ["hinge"]
    """


def revolute(effort: str) -> str:
    return pendulum_urdf('type="revolute"', f'\n<limit lower="-3" upper="3" effort="{effort}" velocity="10"/>')


@pytest.mark.parametrize(
    ("effort", "bound"),
    [("5", 5.0), (f"{MAX_MAGNITUDE:.17g}", MAX_MAGNITUDE), ("1.0000000001e12", math.inf), ("1e20", math.inf),
     ("0", math.inf)],
)  # fmt: skip
def test_effort_limits_are_bounds_up_to_the_ceiling(effort, bound, tmp_path):
    """A URDF effort is a bound up to MAX_MAGNITUDE (1e12 N m: past any actuator); beyond it, or 0 (what exporters
    write when they give none), it is no bound: efforts up to 1e30 were bounds."""
    actuation = load_scene(pendulum_scene(tmp_path, HOLD_LEVEL, revolute(effort))).actuation
    assert (actuation.lower[0], actuation.upper[0]) == (-bound, bound)


def test_a_servo_within_an_effort_limit_at_the_ceiling_holds_the_weight(tmp_path):
    """Effort 1e12 N m (the boundary): the servo holds the pendulum level with u = -m g L (1e-9 relative); an effort of
    5 N m cannot, named with the torque it needs."""
    scene = load_scene(pendulum_scene(tmp_path, HOLD_LEVEL, revolute(f"{MAX_MAGNITUDE:.17g}")))
    trajectory = simulate(scene, duration=0.01)
    np.testing.assert_allclose(trajectory.servo_figures["controls"][:, 0], -G * ARM, rtol=1e-9)
    weak = load_scene(pendulum_scene(tmp_path, HOLD_LEVEL, revolute("5")))
    with pytest.raises(ServoInfeasibleError, match=r"needs hinge = -9\.81 outside \[-5, 5\]"):
        simulate(weak, duration=0.01)


def mjcf_pendulum(tmp_path, force_range: str) -> str:
    (tmp_path / "pendulum.xml").write_text(
        textwrap.dedent(f"""\
            <mujoco model="pendulum">
              <worldbody>
                <body name="arm">
                  <joint name="hinge" type="hinge" axis="0 1 0" actuatorfrclimited="true"
                         actuatorfrcrange="{force_range}"/>
                  <geom type="sphere" size="0.1" pos="{ARM} 0 0" mass="1"/>
                </body>
              </worldbody>
            </mujoco>
            """)
    )
    path = tmp_path / "mjcf.toml"
    path.write_text('[robot]\nmjcf = "pendulum.xml"\n' + textwrap.dedent(HOLD_LEVEL))
    return str(path)


def test_an_mjcf_force_range_is_taken_as_given(tmp_path):
    """actuatorfrcrange="-3 -1": the bounds [-3, -1] N m (read as no bound: Pinocchio's effortLimit is the upper one,
    -1); "nan nan" (read as 7e-310) named."""
    actuation = load_scene(mjcf_pendulum(tmp_path, "-3 -1")).actuation
    assert (actuation.lower[0], actuation.upper[0]) == (-3.0, -1.0)
    with pytest.raises(SceneError, match="joint 'hinge': actuatorfrcrange='nan nan' is not 2 finite numbers"):
        load_scene(mjcf_pendulum(tmp_path, "nan nan"))


def test_every_example_robot_keeps_its_effort_limits():
    """Each example-robot-data robot pinstab reads: its effort limits e in (0, 1e12] are the bounds +-e (all of them
    are: 0.1 to 5e4 N m), the others (0: the double pendulums, iris; 1.8e308 or inf: Cassie, Romeo's unlimited
    joints) none."""
    bounded = 0
    for name in example_robot_names():
        try:
            model = read_robot({"name": name}, ROBOTS).model
        except SceneError:
            continue  # refused for another reason (an inertia, a missing file): not its efforts
        raw = np.asarray(model.effortLimit, dtype=float)
        lower, upper = effort_bounds(model, np.arange(model.nv))
        given = (raw > 0.0) & (raw <= MAX_MAGNITUDE)
        np.testing.assert_array_equal(upper[given], raw[given], err_msg=name)
        np.testing.assert_array_equal(lower[given], -raw[given], err_msg=name)
        assert np.isinf(upper[~given]).all() and np.isinf(lower[~given]).all(), name
        bounded += int(given.sum())
    assert bounded > 500


# -- 4. the servo's realizability, free of the controls' units ---------------------------------------------------------
SWING = """
[[servos]]
name = "swing"
kind = "joint-relation"
joints = { joint1 = 1.0 }
value = "0.5 rad"
sine = { amplitude = "0.2 rad", omega = "3 rad/s" }

[actuation]"""


def two_servos(tmp_path, matrix: str) -> str:
    """double-pendulum-servo with its shoulder prescribed too (a sine about its start), both joints actuated through
    ``matrix``: as many controls as rows, so the motion does not depend on the controls' units."""
    text = (ROBOTS / "double-pendulum-servo.toml").read_text()
    text = text.replace("[actuation]", SWING, 1).replace('joints = ["joint2"]', f"matrix = {matrix}", 1)
    path = tmp_path / f"scaled{len(list(tmp_path.iterdir()))}.toml"
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize("solver", [None, "dense"], ids=["compiled", "general"])
@pytest.mark.parametrize("scales", [(1e12, 1.0), (1.0, 1e-12), (1e12, 1e-12)], ids=str)
def test_scaled_controls_give_the_same_motion(scales, solver, tmp_path):
    """B = diag(s1, s2) against B = I: the same motion (q, v to 1e-10) with controls u_i / s_i (1e-9 relative). B =
    diag(1e12, 1) was refused at t = 0 ('rank 1 < 2': a tolerance relative to the largest singular value), and
    diag(1e12, 1e-12) lost the small control in the pseudo-inverse's cutoff."""
    reference = simulate(load_scene(two_servos(tmp_path, "[[1, 0], [0, 1]]")), duration=0.5, solver=solver)
    matrix = f"[[{scales[0]}, 0], [0, {scales[1]}]]"
    scaled = simulate(load_scene(two_servos(tmp_path, matrix)), duration=0.5, solver=solver)
    assert scaled.info.path == ("servo" if solver is None else "general")
    np.testing.assert_allclose(scaled.q, reference.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(scaled.v, reference.v, rtol=0, atol=1e-10)
    controls = reference.servo_figures["controls"] / np.array(scales)
    np.testing.assert_allclose(scaled.servo_figures["controls"], controls, rtol=1e-9)


def test_the_issue_example_is_realizable(tmp_path, capsys):
    """`pinstab servo` with actuation.matrix = [[1e12, 0], [0, 1]] (two rows): exit 0 (was 2, ServoInfeasibleError)."""
    code = cli.main(["servo", two_servos(tmp_path, "[[1e12, 0], [0, 1]]"), "--duration", "0.2", "--quiet"])
    assert code == 0 and "Traceback" not in capsys.readouterr().err


RNG = np.random.default_rng(34)


def test_realizability_does_not_see_the_units_of_rows_and_controls():
    """The rank and the determinant's sign of D = S N B are those of D with its rows and columns scaled by any positive
    factors in [1e-12, 1e12] (the unit-free matrix the same to 1e-12); dependent rows stay dependent at any scale."""
    rows, moved = RNG.normal(size=(2, 4)), RNG.normal(size=(4, 2))
    unit, rank, sign, _, _ = servo_realizability(rows @ moved, rows, moved, 1e-9)
    dependent = np.array([[1.0, 2.0, 0.0, 1.0], [2.0, 4.0, 0.0, 2.0]])
    for _ in range(20):
        row_scale, column_scale = 10.0 ** RNG.uniform(-12, 12, 2), 10.0 ** RNG.uniform(-12, 12, 2)
        scaled_rows, scaled_moved = row_scale[:, None] * rows, moved * column_scale
        scaled = servo_realizability(scaled_rows @ scaled_moved, scaled_rows, scaled_moved, 1e-9)
        np.testing.assert_allclose(scaled[0], unit, atol=1e-12)
        assert scaled[1:3] == (rank, sign) == (2, sign) and sign in (-1.0, 1.0)
        scaled_dependent = row_scale[:, None] * dependent
        assert servo_realizability(scaled_dependent @ scaled_moved, scaled_dependent, scaled_moved, 1e-9)[1] == 1


def test_least_norm_keeps_a_control_of_small_columns():
    """D = [[1e12, 0], [0, 1e-12]]: u = (1e-12, 2e12) exactly (a pseudo-inverse with rcond 1e-12 dropped the second);
    one row of three controls: D^T d / |D|^2."""
    np.testing.assert_allclose(least_norm(np.diag([1e12, 1e-12]), np.array([1.0, 2.0])), [1e-12, 2e12], rtol=1e-15)
    row = np.array([[1.0, 2.0, 2.0]])
    np.testing.assert_allclose(least_norm(row, np.array([9.0])), [1.0, 2.0, 2.0], rtol=1e-15)
