"""Servo targets that vary in time (pinstab/constraints/targets.py): each trajectory kind against its closed
form and its derivatives against finite differences; the frame-pose rows against differences of their
residual; scenes tracking minimum-jerk, spline and pose targets through `pinstab servo`; bad targets refused
by name; the zero dynamics of double-pendulum-servo reported and its runaway warned about."""

from __future__ import annotations

import json
import math

import numpy as np
import pinocchio as pin
import pytest

from pinstab import ConstrainedModel, simulate
from pinstab.cli import main
from pinstab.constraints.targets import TRAJECTORY_KINDS, TargetContext, read_trajectory
from pinstab.errors import SceneError, WaypointError, ZeroDynamicsWarning
from pinstab.scene import scene_from_dict

SCALAR = TargetContext(1, "coordinate", np.array([0.25]))
POINT = TargetContext(3, "length", np.array([0.1, -0.2, 0.3]))
H = 1e-5  # [s] central-difference step


def evaluate(table: dict, context: TargetContext, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return read_trajectory(table, context, "target").evaluate(t)


def differences(table: dict, context: TargetContext, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(dx/dt, d2x/dt2) by central differences of the value and of the first derivative."""
    trajectory = read_trajectory(table, context, "target")
    before, after = trajectory.evaluate(t - H), trajectory.evaluate(t + H)
    return (after[0] - before[0]) / (2 * H), (after[1] - before[1]) / (2 * H)


TABLES = {
    "polynomial": ({"kind": "polynomial", "coefficients": [1.0, 2.0, -3.0, 0.5]}, SCALAR),
    "polynomial-point": ({"kind": "polynomial", "coefficients": [[0, 1, 2], [1, 0, -1], [0.5, 0.2, 0]]}, POINT),
    "sinusoid": ({"kind": "sinusoid", "amplitude": 0.3, "omega": 2.0, "phase": 0.4}, SCALAR),
    "sinusoid-point": ({"kind": "sinusoid", "amplitude": [0.1, 0, 0.2], "omega": [1.0, 2.0, 3.0]}, POINT),
    "minimum-jerk": ({"kind": "minimum-jerk", "to": 1.5, "start": 0.2, "duration": 1.3}, SCALAR),
    "minimum-jerk-point": ({"kind": "minimum-jerk", "to": [0.2, 0, 0.4], "duration": "1500 ms"}, POINT),
    "cubic-spline": ({"kind": "cubic-spline", "times": [0, 0.5, 1.2, 2], "values": [0, 1, -0.5, 0.3]}, SCALAR),
    "cubic-spline-natural": (
        {"kind": "cubic-spline", "times": [0, 1, 2], "values": [[0, 0, 0], [1, 2, 3], [0, 1, 0]], "ends": "natural"},
        POINT,
    ),
}


@pytest.mark.parametrize("name", TABLES)
@pytest.mark.parametrize("t", [0.3, 0.77, 1.6])
def test_derivatives_match_finite_differences(name, t):
    """dx/dt and d2x/dt2 of every kind equal central differences (h = 1e-5 s) of x and dx/dt to 1e-7 (the
    truncation error h^2 x''' / 6 and rounding are below 1e-8 here)."""
    table, context = TABLES[name]
    _, first, second = evaluate(table, context, t)
    rate, curvature = differences(table, context, t)
    np.testing.assert_allclose(first, rate, atol=1e-7)
    np.testing.assert_allclose(second, curvature, atol=1e-7)


def test_every_kind_is_tested():
    assert {table["kind"] for table, _ in TABLES.values()} == set(TRAJECTORY_KINDS)


def test_polynomial_and_sinusoid_closed_forms():
    """x = 1 + 2t - 3t^2 + 0.5t^3 (with unit deg: times pi/180); offset + A sin(w t + p), offset by default
    the start value; to 1e-15."""
    t = 0.7
    x, v, a = evaluate(TABLES["polynomial"][0], SCALAR, t)
    assert (x[0], v[0], a[0]) == pytest.approx((1 + 2 * t - 3 * t**2 + 0.5 * t**3, 2 - 6 * t + 1.5 * t**2, -6 + 3 * t))
    x, v, a = evaluate({"kind": "polynomial", "coefficients": [10.0, 90.0], "unit": "deg"}, SCALAR, t)
    assert (x[0], v[0], a[0]) == pytest.approx(((10 + 90 * t) * math.pi / 180, math.pi / 2, 0.0), abs=1e-15)
    x, v, a = evaluate(TABLES["sinusoid"][0], SCALAR, t)
    angle = 2 * t + 0.4
    assert (x[0], v[0], a[0]) == pytest.approx(
        (0.25 + 0.3 * math.sin(angle), 0.6 * math.cos(angle), -1.2 * math.sin(angle))
    )


def test_minimum_jerk_closed_form():
    """From the start value 0.25 to 1.5 over [0.2, 1.5] s: rest at both ends (held outside), half way at the
    midpoint with the peak speed 15/8 (1.25)/1.3 and no acceleration, 10 s^3 - 15 s^4 + 6 s^5 at s = 0.3;
    to 1e-12."""
    table = TABLES["minimum-jerk"][0]
    change, duration = 1.25, 1.3
    for t, expected in ((0.0, 0.25), (0.2, 0.25), (1.5, 1.5), (3.0, 1.5)):
        x, v, a = evaluate(table, SCALAR, t)
        assert (x[0], v[0], a[0]) == pytest.approx((expected, 0.0, 0.0), abs=1e-12)
    x, v, a = evaluate(table, SCALAR, 0.2 + duration / 2)
    assert (x[0], v[0], a[0]) == pytest.approx((0.875, 15 / 8 * change / duration, 0.0), abs=1e-12)
    s = 0.3
    x, v, a = evaluate(table, SCALAR, 0.2 + s * duration)
    assert x[0] == pytest.approx(0.25 + change * (10 * s**3 - 15 * s**4 + 6 * s**5), abs=1e-12)
    assert v[0] == pytest.approx(change * 30 * s**2 * (1 - s) ** 2 / duration, abs=1e-12)
    assert a[0] == pytest.approx(change * 60 * s * (1 - s) * (1 - 2 * s) / duration**2, abs=1e-12)


def test_cubic_spline_closed_forms():
    """Through its waypoints; two clamped waypoints give the cubic Hermite x0 + dx (3s^2 - 2s^3); natural
    ends through collinear waypoints give the line (no curvature); held outside the times; to 1e-12."""
    table, context = TABLES["cubic-spline"]
    for t, value in zip(table["times"], table["values"], strict=True):
        assert evaluate(table, context, t)[0][0] == pytest.approx(value, abs=1e-12)
    assert evaluate(table, context, 0.0)[1][0] == pytest.approx(0.0, abs=1e-12)  # clamped: rest at the ends
    hermite = {"kind": "cubic-spline", "times": [1.0, 3.0], "values": [0.5, 2.5]}
    s = 0.35
    x, v, a = evaluate(hermite, SCALAR, 1.0 + 2 * s)
    assert (x[0], v[0], a[0]) == pytest.approx((0.5 + 2 * (3 * s**2 - 2 * s**3), 6 * s * (1 - s), 3 * (1 - 2 * s)))
    assert tuple(float(e[0]) for e in evaluate(hermite, SCALAR, 5.0)) == (2.5, 0.0, 0.0)
    line = {"kind": "cubic-spline", "times": [0, 1, 3], "values": [1, 3, 7], "ends": "natural"}
    x, v, a = evaluate(line, SCALAR, 2.2)
    assert (x[0], v[0], a[0]) == pytest.approx((5.4, 2.0, 0.0), abs=1e-12)


@pytest.mark.parametrize(
    ("table", "error", "pattern"),
    [
        ({"kind": "bezier"}, SceneError, r"target: unknown trajectory kind 'bezier'; valid kinds: cubic-spline, "),
        ({"amplitude": 1}, SceneError, r"unknown trajectory kind None; valid kinds: cubic-spline, minimum-jerk"),
        ({"kind": "cubic-spline", "times": [0, 2, 1], "values": [0, 1, 2]}, WaypointError, r"times\[2\] = 1 s after"),
        ({"kind": "cubic-spline", "times": [0, 1, 1], "values": [0, 1, 2]}, WaypointError, r"increase strictly"),
        ({"kind": "cubic-spline", "times": [0, 1, 2], "values": [0, 1]}, WaypointError, r"3 times and 2 values"),
        ({"kind": "cubic-spline", "times": [0], "values": [0]}, WaypointError, r"at least 2"),
        ({"kind": "cubic-spline", "times": [0, 1], "values": [0, 1], "ends": "free"}, SceneError, r"'free'; valid"),
        ({"kind": "minimum-jerk", "to": 1, "duration": 0}, SceneError, r"duration must be positive"),
        ({"kind": "minimum-jerk", "to": 1}, SceneError, r"'to' and 'duration' are required"),
        ({"kind": "polynomial", "coefficients": []}, SceneError, r"non-empty list"),
        ({"kind": "polynomial", "coefficients": [1], "unit": "kg"}, SceneError, r"unit 'kg' is not a unit of"),
        ({"kind": "sinusoid", "amplitud": 1}, SceneError, r"unknown key 'amplitud'; valid keys: amplitude"),
        ("sin(t)", SceneError, r"target must be a table"),
    ],
)
def test_bad_targets_are_named(table, error, pattern):
    with pytest.raises(error, match=pattern):
        read_trajectory(table, SCALAR, "target")


def test_unknown_kind_in_a_scene_names_the_servo():
    data = relation_scene({"kind": "quintic", "to": 1.0})
    with pytest.raises(SceneError, match=r"servo 'arm'\.target: unknown trajectory kind 'quintic'; valid kinds: "):
        scene_from_dict(data)
    data["servos"][0]["value"] = 0.3
    with pytest.raises(SceneError, match=r"give either 'target' or 'value', not both"):
        scene_from_dict(data)


def relation_scene(target: dict, elbow: dict | None = None) -> dict:
    """The double pendulum, both joints actuated: joint1 on ``target``, joint2 on ``elbow`` (default held)."""
    return {
        "robot": {"name": "double_pendulum"},
        "servos": [
            {"name": "arm", "kind": "joint-relation", "joints": {"joint1": 1.0}, "target": target},
            {
                "name": "elbow",
                "kind": "joint-relation",
                "joints": {"joint2": 1.0},
                "target": elbow or {"kind": "sinusoid"},
            },
        ],
        "actuation": {"joints": ["joint1", "joint2"]},
        "initial": {"q": {"joint1": 0.2, "joint2": -0.3}},
    }


TRACKED = """
[robot]
name = "double_pendulum"

[[servos]]
name = "arm"
kind = "joint-relation"
joints = { joint1 = 1.0 }
target = { kind = "minimum-jerk", to = "60 deg", start = 0.2, duration = 1.0 }

[[servos]]
name = "elbow"
kind = "joint-relation"
joints = { joint2 = 1.0 }
target = { kind = "cubic-spline", times = [0, 0.5, 1.0, 1.5], values = [-0.3, 0.4, 0.0, 0.5] }

[actuation]
joints = ["joint1", "joint2"]

[initial]
q = { joint1 = 0.2, joint2 = -0.3 }
"""


def test_minimum_jerk_and_spline_targets_are_tracked_by_pinstab_servo(tmp_path, capsys):
    """`pinstab servo` on the double pendulum, joint1 on a minimum-jerk move (0.2 rad to 60 deg over [0.2, 1.2]
    s), joint2 on a clamped spline through 4 waypoints: the servo error stays <= 1e-8 rad over 1.5 s and the
    joints equal the closed forms at every sample (<= 1e-8 rad); both joints are servoed, so no coordinate is
    left free."""
    path = tmp_path / "tracked.toml"
    path.write_text(TRACKED)
    saved = tmp_path / "run.npz"
    assert main(["servo", str(path), "--duration", "1.5", "--json", "--quiet", "--save", str(saved)]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["max_servo_error"] <= 1e-8
    assert result["zero_dynamics"]["free_coordinates"] == []
    from pinstab.trajectory import Trajectory

    trajectory = Trajectory.load(saved)
    s = np.clip((trajectory.t - 0.2) / 1.0, 0, 1)
    expected = 0.2 + (math.pi / 3 - 0.2) * (10 * s**3 - 15 * s**4 + 6 * s**5)
    assert np.max(np.abs(trajectory.q[:, 0] - expected)) <= 1e-8
    spline = read_trajectory(
        {"kind": "cubic-spline", "times": [0, 0.5, 1.0, 1.5], "values": [-0.3, 0.4, 0.0, 0.5]}, SCALAR, "elbow"
    )
    elbow = np.array([spline.evaluate(t)[0][0] for t in trajectory.t])
    assert np.max(np.abs(trajectory.q[:, 1] - elbow)) <= 1e-8


def panda_pose() -> dict:
    """The Panda (fingers locked, 7 joints actuated), its flange on a 4 cm ellipse in the y-z plane and turned
    by 30 deg about the world z axis in a minimum-jerk move over 1 s (frame-pose servo, 6 rows), panda_joint3
    on a cubic spline (7 rows, square)."""
    joints = [f"panda_joint{i}" for i in range(1, 8)]
    start = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
    return {
        "robot": {"name": "panda", "locked_joints": ["panda_finger_joint1", "panda_finger_joint2"]},
        "servos": [
            {
                "name": "pose",
                "kind": "frame-pose",
                "frame": "panda_link8",
                "path": {"kind": "sinusoid", "amplitude": [0.0, 0.04, 0.02], "omega": 2.0},
                "turn": {"kind": "minimum-jerk", "to": "30 deg", "duration": 1.0},
            },
            {
                "name": "elbow",
                "kind": "joint-relation",
                "joints": {"panda_joint3": 1.0},
                "target": {"kind": "cubic-spline", "times": [0, 0.8, 1.6], "values": [0, 0.2, 0.1]},
            },
        ],
        "actuation": {"joints": joints},
        "initial": {
            "q": {**dict(zip(joints, start, strict=True)), "panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
        },
    }


def test_frame_pose_rows_are_derivatives():
    """frame-pose at a configuration off its target, t = 0.4 s (mid-turn): G = d phi/dq, g_t = d phi/dt, and
    gamma0 = d/ds (G v + g_t) along q + s v, t + s (zero joint acceleration; the Panda's joints are all
    revolute), by central differences (1e-6) to 1e-6."""
    scene = scene_from_dict(panda_pose())
    pose = scene.constraints[0]
    model = ConstrainedModel(scene)
    kin, nv = model.kin, scene.model.nv
    rng = np.random.default_rng(5)
    q = pin.integrate(scene.model, scene.q0, 0.2 * rng.standard_normal(nv))
    v = rng.standard_normal(nv)
    t, h = 0.4, 1e-6

    def residual(q_: np.ndarray, t_: float) -> np.ndarray:
        kin.update_positions(q_)
        return pose.residual(kin, q_, t_)

    def velocity_residual(s: float) -> np.ndarray:
        moved = q + s * v
        kin.update_jacobians(moved)
        jacobian, time_term = pose.velocity_terms(kin, moved, t + s)
        return jacobian @ v + time_term

    kin.update_jacobians(q)
    jacobian, time_term = pose.velocity_terms(kin, q, t)
    columns = [(residual(q + h * e, t) - residual(q - h * e, t)) / (2 * h) for e in np.eye(nv)]
    np.testing.assert_allclose(jacobian, np.array(columns).T, atol=1e-6)
    np.testing.assert_allclose(time_term, (residual(q, t + h) - residual(q, t - h)) / (2 * h), atol=1e-6)
    kin.update(q, v)
    drift = pose.drift(kin, q, v, t)
    np.testing.assert_allclose(drift, (velocity_residual(h) - velocity_residual(-h)) / (2 * h), atol=1e-6)


def test_frame_pose_servo_follows_the_turn():
    """The Panda's flange on the pose target for 1.5 s: servo error <= 1e-8, and at the end its rotation is the
    start one turned by 30 deg about world z (<= 1e-8 rad) and its point on the ellipse (<= 1e-8 m)."""
    scene = scene_from_dict(panda_pose())
    pose = scene.constraints[0]
    trajectory = simulate(scene, integrator="rk4", dt=2e-3, duration=1.5, progress=False)
    assert np.nanmax(trajectory.servo_figures["servo_error"]) <= 1e-8
    model = ConstrainedModel(scene)
    model.kin.update_positions(scene.q0)
    start = model.kin.placement(pose.frame).copy()
    model.kin.update_positions(trajectory.q[-1])
    end = model.kin.placement(pose.frame)
    turned = pin.exp3(np.array([0.0, 0.0, math.pi / 6])) @ start.rotation
    assert np.linalg.norm(pin.log3(turned.T @ end.rotation)) <= 1e-8
    ellipse = start.translation + np.array([0.0, 0.04, 0.02]) * math.sin(3.0)
    assert np.linalg.norm(end.translation - ellipse) <= 1e-8


def test_two_cars_zero_dynamics_is_the_spring_oscillator(recwarn):
    """two-cars: car 1 is prescribed, car 2 is free on the spring, m2 x2'' = -k (x2 - x1): the zero dynamics'
    eigenvalues are +-i sqrt(k/m2) = +-i sqrt(5) 1/s (to 1e-6), undamped, and car 2 (speed <= 1 m/s) does not
    run away: no warning."""
    trajectory = simulate("two-cars", dt=1e-3, duration=2.0, progress=False)
    report = trajectory.zero_dynamics
    assert report["free_coordinates"] == ["x2"]
    eigenvalues = sorted(complex(*pair).imag for pair in report["eigenvalues_at_start"])
    assert [complex(*pair).real for pair in report["eigenvalues_at_start"]] == pytest.approx([0, 0], abs=1e-6)
    assert eigenvalues == pytest.approx([-math.sqrt(5.0), math.sqrt(5.0)], abs=1e-6)
    assert report["character"] == "undamped" and report["runaway"] == []
    assert not [w for w in recwarn if issubclass(w.category, ZeroDynamicsWarning)]


def pendulum_relation(shoulder: float) -> dict:
    """double-pendulum-servo's relation joint2 + 0.5 joint1 = c held constant, c = 0.5 shoulder, from rest at
    joint1 = shoulder."""
    return {
        "robot": {"name": "double_pendulum"},
        "servos": [{"name": "shape", "kind": "joint-relation", "joints": {"joint2": 1.0, "joint1": 0.5}, "value": 0.0}],
        "actuation": {"joints": ["joint2"]},
        "initial": {"q": {"joint1": shoulder, "joint2": -0.5 * shoulder}},
    }


def reduced_pendulum(scene, shoulder: float) -> tuple[float, float, float]:
    """The passive shoulder's equation on joint2 = -joint1/2, alpha(x) x'' + beta(x) x'^2 + gamma(x) = 0, from
    Pinocchio's M and gravity g(q): (alpha = M11 - M12/2 [kg m^2], gamma [N m], dgamma/dx by central
    differences [N m/rad]) at joint1 = shoulder."""
    model, data = scene.model, scene.model.createData()

    def gamma(x: float) -> float:
        return float(pin.computeGeneralizedGravity(model, data, np.array([x, -0.5 * x]))[0])

    mass = pin.crba(model, data, np.array([shoulder, -0.5 * shoulder]))
    return mass[0, 0] - 0.5 * mass[0, 1], gamma(shoulder), (gamma(shoulder + 1e-6) - gamma(shoulder - 1e-6)) / 2e-6


@pytest.mark.parametrize("where", ["top", "bottom"])
def test_pendulum_zero_dynamics_against_the_reduced_equation(where):
    """At the equilibria of the shoulder's reduced equation (gamma = 0: upright, joint1 = 0; hanging, found by
    bisection) the zero dynamics' eigenvalues are +-sqrt(-gamma'/alpha): real (a saddle, unstable) at the top,
    imaginary (undamped) at the bottom; to 1e-5 relative."""
    scene = scene_from_dict(pendulum_relation(0.0))
    shoulder = 0.0
    if where == "bottom":
        low, high = 2.5, 4.5  # gamma changes sign once between (the hanging configuration, joint1 ~ 3.6 rad)
        for _ in range(100):
            middle = 0.5 * (low + high)
            low, high = (
                (middle, high)
                if reduced_pendulum(scene, low)[1] * reduced_pendulum(scene, middle)[1] > 0
                else (low, middle)
            )
        shoulder = 0.5 * (low + high)
    alpha, _, slope = reduced_pendulum(scene, shoulder)
    rate = complex(-slope / alpha) ** 0.5
    trajectory = simulate(scene_from_dict(pendulum_relation(shoulder)), dt=1e-3, duration=0.002, progress=False)
    report = trajectory.zero_dynamics
    assert report["free_coordinates"] == ["joint1"]
    found = sorted((complex(*pair) for pair in report["eigenvalues_at_start"]), key=lambda e: (e.real, e.imag))
    expected = sorted([rate, -rate], key=lambda e: (e.real, e.imag))
    np.testing.assert_allclose(np.array(found), np.array(expected), rtol=1e-5, atol=1e-6 * abs(rate))
    assert report["character"] == ("unstable" if where == "top" else "undamped")


def test_double_pendulum_servo_runaway_is_warned(capsys):
    """`pinstab servo double-pendulum-servo --duration 2`: the free shoulder (joint1) whirls from 0.39 to over
    160 rad/s (167.0 at t = 1.458 s); the JSON reports it, its zero dynamics at the start is a saddle (+-7
    1/s), and the CLI prints the ZeroDynamicsWarning naming joint1."""
    assert main(["servo", "double-pendulum-servo", "--duration", "2", "--json", "--quiet"]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)["zero_dynamics"]
    assert report["runaway"] == ["joint1"] and report["character"] == "unstable"
    assert report["coordinates"]["joint1"]["max_speed"] > 160.0
    assert [pair[0] for pair in report["eigenvalues_at_start"]] == pytest.approx([7.0, -7.07], abs=0.01)
    assert "pinstab servo: warning: scene double-pendulum-servo: free coordinates ran away" in captured.err
    assert "joint1 reached 167" in captured.err


def test_the_fall_not_the_sine_runs_the_shoulder_away():
    """With double-pendulum-servo's relation held constant (no sine), from rest 0.4 rad off the top, the
    shoulder still runs away (ZeroDynamicsWarning naming joint1): past 100 rad/s within 0.5 s (123.7 at
    0.438 s), from a saddle of eigenvalues +-7.03 1/s; the elbow torque works on the links (gravity alone
    would keep the energy at its 0.92 J start: it rises past 10 J, 14.6 J)."""
    scene = scene_from_dict(pendulum_relation(0.4))
    with pytest.warns(ZeroDynamicsWarning, match=r"joint1 reached 12\d\.\d at t = 0\.4"):
        trajectory = simulate(scene, dt=1e-3, duration=0.5, progress=False)
    entry = trajectory.zero_dynamics["coordinates"]["joint1"]
    assert entry["start_speed"] == 0.0 and entry["max_speed"] > 100.0
    assert trajectory.energy[0] == pytest.approx(0.915, abs=1e-3) and trajectory.energy.max() > 10.0
    assert [pair[0] for pair in trajectory.zero_dynamics["eigenvalues_at_start"]] == pytest.approx(
        [7.03, -7.03], abs=0.01
    )
