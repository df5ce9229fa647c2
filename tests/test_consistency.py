"""Issue 34, items 1 (servo targets) and 5: the target trajectories' durations, times, values and coefficients
checked against ranges before any work (their boundaries accepted and tracked to the closed forms); one behaviour
per input across commands and flags: ``check`` refuses the start ``run`` refuses, ``--json`` keeps the exit code, and
stdout holds nothing but the JSON, also when C or Fortran code writes to file descriptor 1."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from numpy.polynomial import polynomial

from conftest import ROBOTS
from pinstab import cli
from pinstab.cli.commands import COMMANDS
from pinstab.constraints.targets import MAX_DEGREE, MAX_OMEGA, MAX_TIME, MIN_SPAN, TargetContext, read_trajectory
from pinstab.errors import SceneError, WaypointError
from pinstab.scene import scene_from_dict
from pinstab.tables import MAX_REACH, scene_size
from pinstab.trajectory import Trajectory
from pinstab.units import MAX_COORDINATE, MAX_MAGNITUDE

SCALAR = TargetContext(1, "coordinate", np.array([0.25]))
POINT = TargetContext(3, "length", np.array([0.1, -0.2, 0.3]))
START = 0.2  # [rad] joint1's start in the servo scenes
TO = math.pi / 3  # [rad] the minimum-jerk move's end


def servo_scene(target: str, limits: str = "") -> str:
    """The double pendulum, both joints actuated: joint1 on ``target`` (a TOML inline table), joint2 held."""
    return textwrap.dedent(f"""\
        [robot]
        name = "double_pendulum"

        [[servos]]
        name = "arm"
        kind = "joint-relation"
        joints = {{ joint1 = 1.0 }}
        target = {target}

        [[servos]]
        name = "elbow"
        kind = "joint-relation"
        joints = {{ joint2 = 1.0 }}
        target = {{ kind = "sinusoid" }}

        [actuation]
        joints = ["joint1", "joint2"]

        [initial]
        q = {{ joint1 = {START}, joint2 = -0.3 }}
        """)


def write(tmp_path, name: str, text: str) -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def run(capsys, *argv: str) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of the command line in this process."""
    quiet = ["--quiet"] if argv[0] in cli.SIMULATING else []
    code = cli.main([*argv, *quiet])
    out, err = capsys.readouterr()
    return code, out, err


# -- servo target ranges (item 1) ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("table", "context", "error", "phrase"),
    [
        (
            {"kind": "minimum-jerk", "to": 1, "duration": 1e-300},
            SCALAR,
            SceneError,
            "target (minimum-jerk).duration = 1e-300 s is outside the allowed range [1e-06, 1e+09] s",
        ),
        ({"kind": "minimum-jerk", "to": 1, "duration": "0.9e-3 ms"}, SCALAR, SceneError, "duration = 9e-07 s is out"),
        ({"kind": "minimum-jerk", "to": 1, "duration": 2e9}, SCALAR, SceneError, "duration = 2e+09 s is outside"),
        ({"kind": "minimum-jerk", "to": 1, "duration": 1, "start": -2e9}, SCALAR, SceneError, "start = -2e+09 s is"),
        (
            {"kind": "minimum-jerk", "to": 2e6, "duration": 1},
            SCALAR,
            SceneError,
            "to = 2e+06 m or rad is outside the allowed range [-1e+06, 1e+06] m or rad",
        ),
        (
            {"kind": "polynomial", "coefficients": [0.2, 0, 1e308]},
            SCALAR,
            SceneError,
            "coefficients[2] = 1e+308 (m or rad)/s^2 is outside the allowed range [-1e+12, 1e+12] (m or rad)/s^2",
        ),
        ({"kind": "polynomial", "coefficients": [-1e7]}, SCALAR, SceneError, "coefficients[0] = -1e+07 m or rad"),
        (  # checked in SI: 1e14 deg/s = 1.75e12 rad/s
            {"kind": "polynomial", "coefficients": [0, 1e14], "unit": "deg"},
            TargetContext(1, "angle", np.zeros(1)),
            SceneError,
            "coefficients[1] = 1.75e+12 rad/s is outside",
        ),
        (
            {"kind": "polynomial", "coefficients": [[0, 0, 0], [0, 0, -2e12]]},
            POINT,
            SceneError,
            "coefficients[1][2] = -2e+12 m/s is",
        ),
        ({"kind": "polynomial", "coefficients": [1.0] * 17}, SCALAR, SceneError, "17 coefficients, a polynomial of "),
        ({"kind": "sinusoid", "amplitude": 1, "omega": 3.2e6}, SCALAR, SceneError, "omega = 3.2e+06 rad/s is out"),
        ({"kind": "sinusoid", "amplitude": 1, "phase": 1e7}, SCALAR, SceneError, "phase = 1e+07 rad is outside"),
        ({"kind": "sinusoid", "amplitude": [0, 2e6, 0]}, POINT, SceneError, "amplitude[1] = 2e+06 m is outside"),
        (
            {"kind": "cubic-spline", "times": [0, 5e-7], "values": [0, 1]},
            SCALAR,
            WaypointError,
            "times[1] = 5e-07 s is 5e-07 s after times[0]; waypoints at least 1e-06 s apart",
        ),
        ({"kind": "cubic-spline", "times": [0, 2e9], "values": [0, 1]}, SCALAR, SceneError, "times[1] = 2e+09 s is"),
        ({"kind": "cubic-spline", "times": [0, 1], "values": [0, 1e300]}, SCALAR, SceneError, "values[1] = 1e+300"),
    ],
)
def test_target_values_beyond_their_ranges_are_refused_by_name(table, context, error, phrase):
    with pytest.raises(error) as raised:
        read_trajectory(table, context, "target")
    assert phrase in str(raised.value)


def test_the_boundaries_of_the_ranges_are_accepted_and_exact():
    """Each range's end is read and evaluated exactly, against closed forms computed here: a minimum-jerk of
    MIN_SPAN (at its middle: half the change, slope 1.875 change / duration, no curvature), starting at -MAX_TIME,
    a polynomial of degree MAX_DEGREE with coefficients +-MAX_MAGNITUDE (numpy's polyval and polyder), a sinusoid of
    omega MAX_OMEGA and amplitude MAX_COORDINATE, a spline through waypoints MIN_SPAN apart (its values at them)."""
    change = 1.0 - 0.25
    move = read_trajectory({"kind": "minimum-jerk", "to": 1.0, "duration": MIN_SPAN}, SCALAR, "target")
    x, v, a = (float(e[0]) for e in move.evaluate(MIN_SPAN / 2))
    assert (x, v) == pytest.approx((0.25 + change / 2, 1.875 * change / MIN_SPAN), rel=1e-14) and abs(a) < 1e-3
    early = read_trajectory({"kind": "minimum-jerk", "to": 1.0, "duration": 1, "start": -MAX_TIME}, SCALAR, "t")
    assert [float(e[0]) for e in early.evaluate(0.0)] == [1.0, 0.0, 0.0]  # long finished
    c = [0.5] + [MAX_MAGNITUDE * (-1) ** k for k in range(1, MAX_DEGREE + 1)]
    curve = read_trajectory({"kind": "polynomial", "coefficients": c}, SCALAR, "target")
    t = 0.37
    exact = [polynomial.polyval(t, polynomial.polyder(c, m)) for m in range(3)]
    assert [float(e[0]) for e in curve.evaluate(t)] == pytest.approx(exact, rel=1e-13)
    wave = read_trajectory({"kind": "sinusoid", "amplitude": MAX_COORDINATE, "omega": MAX_OMEGA}, SCALAR, "target")
    x, v, a = (float(e[0]) for e in wave.evaluate(MIN_SPAN / 2))  # a quarter period: the crest
    assert x == pytest.approx(0.25 + MAX_COORDINATE, rel=1e-15) and abs(v) <= 1e-3 * MAX_COORDINATE * MAX_OMEGA
    assert a == pytest.approx(-MAX_COORDINATE * MAX_OMEGA**2, rel=1e-12)
    spline = read_trajectory({"kind": "cubic-spline", "times": [0, MIN_SPAN], "values": [0, 1]}, SCALAR, "target")
    assert [float(spline.evaluate(s)[0][0]) for s in (0.0, MIN_SPAN / 2, MIN_SPAN)] == pytest.approx([0, 0.5, 1])


@pytest.mark.parametrize("json_flag", [[], ["--json"]])
@pytest.mark.parametrize(
    ("target", "phrase"),
    [
        (  # the issue's ZeroDivisionError
            '{ kind = "minimum-jerk", to = "60 deg", start = 0.2, duration = 1e-300 }',
            "servo 'arm'.target (minimum-jerk).duration = 1e-300 s is outside the allowed range [1e-06, 1e+09] s",
        ),
        (  # the issue's exit 3, and 1 with a traceback with --json
            '{ kind = "polynomial", coefficients = [0.2, 0, 1e308] }',
            "servo 'arm'.target (polynomial).coefficients[2] = 1e+308 (m or rad)/s^2 is outside the allowed range",
        ),
    ],
)
def test_the_issues_servo_targets_exit_2_before_any_work(capsys, tmp_path, target, phrase, json_flag):
    code, out, err = run(capsys, "servo", write(tmp_path, "s.toml", servo_scene(target)), *json_flag)
    assert code == 2 and phrase in err and "Traceback" not in err and out == ""


def servo_error(capsys, tmp_path, target: str, dt: float, duration: float, exact) -> float:
    """The largest |joint1 - exact(t)| [rad] of `pinstab servo` with ``target`` (exit 0)."""
    saved = tmp_path / "run.npz"
    scene = write(tmp_path, "s.toml", servo_scene(target))
    code, _, err = run(capsys, "servo", scene, "--dt", str(dt), "--duration", str(duration), "--save", str(saved))
    assert code == 0, err
    trajectory = Trajectory.load(saved)
    return float(np.max(np.abs(trajectory.q[:, 0] - exact(trajectory.t))))


def test_a_minimum_jerk_move_of_the_shortest_duration_is_tracked_to_its_closed_form(capsys, tmp_path):
    """A move of MIN_SPAN = 1 us from 0.2 rad to 60 deg: joint1 follows the quintic with rk4's fourth order (dt
    halved: the error / 16, within 20 %), within 1e-8 rad at dt = 10 ns."""

    def quintic(t):
        s = np.clip(t / MIN_SPAN, 0.0, 1.0)
        return START + (TO - START) * (10 * s**3 - 15 * s**4 + 6 * s**5)

    target = f'{{ kind = "minimum-jerk", to = "60 deg", duration = {MIN_SPAN!r} }}'
    coarse, fine = (servo_error(capsys, tmp_path, target, dt, 1.2e-6, quintic) for dt in (1e-8, 5e-9))
    assert coarse <= 1e-8 and 16 / 1.2 <= coarse / fine <= 16 * 1.2


def test_a_polynomial_at_the_coefficient_ceiling_is_tracked(capsys, tmp_path):
    """joint1 = 0.2 + MAX_MAGNITUDE t^2 [rad] (2e12 rad/s^2) over 1 us: to 1e-13 rad (rk4 is exact on a quadratic:
    rounding only)."""
    target = f'{{ kind = "polynomial", coefficients = [{START}, 0, {MAX_MAGNITUDE!r}] }}'
    error = servo_error(capsys, tmp_path, target, 1e-8, 1e-6, lambda t: START + MAX_MAGNITUDE * t**2)
    assert error <= 1e-13


def test_a_point_target_beyond_the_scenes_reach_is_refused_and_an_axis_of_any_scale_is_a_direction():
    """A frame-path's amplitude, a polynomial's first point and a minimum-jerk goal beyond MAX_REACH scene sizes are
    refused by name; a frame-pose axis of length 1e300 or 1e-300 is the unit z axis (1e300 overflowed the norm)."""
    data = scene_from_dict({"robot": {"name": "double_pendulum"}})
    reach = MAX_REACH * scene_size(data.model, data.q0)
    paths = {
        "amplitude": {"amplitude": [0, 1.5 * reach, 0], "omega": 1.0},
        "path (polynomial).coefficients[0]": {"path": {"kind": "polynomial", "coefficients": [[0, 0, 1.5 * reach]]}},
        "path (minimum-jerk).to": {"path": {"kind": "minimum-jerk", "to": [1.5 * reach, 0, 0], "duration": 1}},
    }
    for name, fields in paths.items():
        servo = {"name": "hand", "kind": "frame-path", "frame": "link2", **fields}
        with pytest.raises(SceneError, match=r"beyond 10 times the scene's size") as raised:
            scene_from_dict({"robot": {"name": "double_pendulum"}, "servos": [servo]})
        assert "servo 'hand'" in str(raised.value) and name in str(raised.value)
    for scale in (1e300, 1e-300):
        pose = {"name": "hand", "kind": "frame-pose", "frame": "link2", "axis": [0, 0, scale]}
        scene = scene_from_dict({"robot": {"name": "double_pendulum"}, "closures": [pose]})
        assert scene.constraints[0].axis.tolist() == [0.0, 0.0, 1.0]


# -- check refuses what run refuses (item 5) -------------------------------------------------------------------------
LIMITED = """\
[robot]
urdf_text = \"\"\"<robot name="pendulum"><link name="base"/>
  <link name="rod"><inertial><origin xyz="0 0 -0.5"/><mass value="2"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="rod"/><axis xyz="0 1 0"/>
    <limit lower="1.3" upper="3.0" effort="100" velocity="100"/></joint>
</robot>\"\"\"

[[servos]]
name = "swing"
kind = "joint-relation"
joints = { hinge = 1.0 }
target = { kind = "sinusoid", amplitude = 0.1, omega = 1.0 }

[actuation]
joints = ["hinge"]

[initial]
q = { hinge = 1.2 }
"""


def test_check_refuses_a_start_outside_the_joint_limits_with_runs_message(capsys, tmp_path):
    """The hinge starts at 1.2 rad, below its lower limit 1.3: run, servo, servo --check and check all exit 2 with
    the same message (check accepted it); with --ignore-limits check and servo --check pass."""
    scene = write(tmp_path, "limited.toml", LIMITED)
    messages = set()
    for argv in (["run"], ["servo"], ["servo", "--check"], ["check"]):
        code, _, err = run(capsys, argv[0], scene, *argv[1:])
        assert code == 2 and "Traceback" not in err, (argv, err)
        messages.add(err.split(": error: ", 1)[1])
    (message,) = messages
    assert message.startswith("scene limited: the start is outside the joint limits: hinge = 1.2 beyond its lower")
    for argv in (["check"], ["servo", "--check"]):
        code, _, err = run(capsys, argv[0], scene, *argv[1:], "--ignore-limits")
        assert code == 0, err


# -- --json keeps the exit code (item 5) -----------------------------------------------------------------------------
BOX_PUSH = (ROBOTS / "box-push.toml").read_text().replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
FAILING = {  # name: (argv with {scene} for the scene file, the scene's text or None, the exit code)
    "bad input": (["run", "fourbar", "--duration", "0"], None, 2),
    "bad servo target": (["servo", "{scene}"], servo_scene('{ kind = "minimum-jerk", to = 1, duration = 1e-300 }'), 2),
    "start outside the limits": (["check", "{scene}"], LIMITED, 2),
    "divergence": (
        "run fourbar --method baumgarte --kp 1e6 --kd 2e3 --integrator euler --dt 1e-2 --duration 5".split(),
        None,
        3,
    ),
    "servo divergence": (
        ["servo", "{scene}", "--duration", "0.5"],
        servo_scene(f'{{ kind = "polynomial", coefficients = [0.2, 0, {MAX_MAGNITUDE!r}] }}'),
        3,
    ),
    "stop-on": (
        "run bouncing-ball --duration 2 --dt 0.01 --stop-on separation".split(),
        None,
        4,
    ),
    "contact failure": (
        ["run", "{scene}", "--contacts", "held", "--duration", "0.1"],
        BOX_PUSH.replace('"1 N"', '"6 N"', 1),
        5,
    ),
}


@pytest.mark.parametrize("name", FAILING)
def test_json_never_changes_the_exit_code(capsys, tmp_path, name):
    """Each failing input ends in the same exit code with and without --json, without a traceback; with --json
    stdout is empty (bad input) or one JSON object (a run that stopped: its figures up to there)."""
    argv, text, expected = FAILING[name]
    scene = write(tmp_path, "scene.toml", text) if text else ""
    argv = [part.replace("{scene}", scene) for part in argv]
    code, out, err = run(capsys, *argv)
    assert code == expected and "Traceback" not in err, err
    code, out, err = run(capsys, *argv, "--json")
    assert code == expected and "Traceback" not in err, err
    if expected == 2:
        assert out == ""
    else:
        assert isinstance(json.loads(out), dict)


def test_a_start_too_fast_for_its_figures_is_refused_alike_with_json(capsys, tmp_path):
    """The issue's servo target of 1e308 diverged at the first step, and its figures up to the last finite state
    (the servo's controls there, where the dynamics were not finite) raised again while the JSON was built: exit 1
    and a traceback with --json, 3 without. The target is refused now, and so is the other start whose dynamics
    overflow (1e160 rad/s: initial.v within MAX_RATE): exit 2 both ways, named, nothing on stdout."""
    start = "q = { joint1 = 0.5 }"
    text = (ROBOTS / "double-pendulum-servo.toml").read_text().replace(start, f"{start}\nv = {{ joint1 = 1e160 }}")
    argv = ["servo", write(tmp_path, "fast.toml", text), "--duration", "0.01"]
    assert run(capsys, *argv)[0] == 2
    code, out, err = run(capsys, *argv, "--json")
    assert code == 2 and "Traceback" not in err and "initial.v.joint1: 1e+160 is outside [-1e+06, 1e+06]" in err
    assert out == ""


# -- nothing but JSON on stdout (item 5) -----------------------------------------------------------------------------
NOISY = """\
import ctypes, dataclasses, sys
import numpy as np
from pinstab.cli import main
from pinstab.cli.commands import COMMANDS


def noisy(execute):
    def work(args):
        try:
            return execute(args)
        finally:  # last: LAPACK's complaint (DLASCL, from OpenBLAS), a printf left in C's buffer, a Python print
            try:
                np.linalg.lstsq(np.array([[np.inf, 1.0], [1.0, 1.0]]), np.ones(2), rcond=None)
            except np.linalg.LinAlgError:
                pass
            ctypes.CDLL(None).printf(b"C-LEVEL NOISE\\n")
            print("PYTHON NOISE")

    return work


for name, command in list(COMMANDS.items()):
    COMMANDS[name] = dataclasses.replace(command, execute=noisy(command.execute))
sys.exit(main(sys.argv[1:]))
"""


def noisy_cli(tmp_path, *argv: str) -> subprocess.CompletedProcess:
    """The command line in a child whose command, at its end, writes to descriptor 1 from C (LAPACK, printf) and
    Python; C's stdout buffered as in a shell (PYTHONUNBUFFERED unset)."""
    script = tmp_path / "noisy.py"
    script.write_text(NOISY)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
    return subprocess.run(
        [sys.executable, str(script), *argv], capture_output=True, text=True, env=env, timeout=120, check=False
    )


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["check", "fourbar"], 0),
        ("run fourbar --method baumgarte --kp 1e6 --kd 2e3 --integrator euler --dt 1e-2 --duration 5".split(), 3),
    ],
)
def test_json_stdout_holds_the_json_alone_when_c_code_writes_to_descriptor_1(tmp_path, argv, expected):
    """What C, Fortran and Python write to descriptor 1 during the command goes to stderr with --json; stdout parses
    as JSON. Without --json it stays on stdout (the noise is real)."""
    completed = noisy_cli(tmp_path, *argv, "--json", "--quiet")
    assert completed.returncode == expected, completed.stderr
    assert json.loads(completed.stdout)["scene"] == "fourbar"
    assert "C-LEVEL NOISE" in completed.stderr and "PYTHON NOISE" in completed.stderr
    assert "DLASCL" not in completed.stdout
    plain = noisy_cli(tmp_path, *argv, "--quiet")
    assert plain.returncode == expected and "C-LEVEL NOISE" in plain.stdout and "PYTHON NOISE" in plain.stdout


def test_the_issues_closure_offset_leaves_stdout_empty(tmp_path):
    """The fourbar closure offset of -1e308 (LAPACK's DLASCL complaints on stdout broke --json): refused by name
    before any work, exit 2, nothing on stdout."""
    text = (ROBOTS / "fourbar.toml").read_text().replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
    scene = write(tmp_path, "fourbar.toml", text.replace("offset_a = [0.6, 0.0, 0.0]", "offset_a = [-1e308, 0, 0]"))
    for command in ("check", "run"):
        completed = noisy_cli(tmp_path, command, scene, "--json", "--quiet")
        assert completed.returncode == 2 and "offset_a" in completed.stderr, completed.stderr
        assert completed.stdout == "" and "Traceback" not in completed.stderr


def test_descriptor_1_is_restored_on_every_way_out(capsys, monkeypatch):
    """After a result, an error and Ctrl-C inside a --json command, descriptor 1 is the file it was before."""
    before = os.fstat(1)

    def interrupted(args):
        raise KeyboardInterrupt

    assert run(capsys, "check", "fourbar", "--json")[0] == 0
    assert run(capsys, "check", "no-such-scene", "--json")[0] == 2
    monkeypatch.setitem(COMMANDS, "check", dataclasses.replace(COMMANDS["check"], execute=interrupted))
    assert run(capsys, "check", "fourbar", "--json")[0] == 130
    after = os.fstat(1)
    assert (after.st_dev, after.st_ino) == (before.st_dev, before.st_ino)


@pytest.mark.parametrize(("argv", "expected"), [(["check", "fourbar"], 0), (["run", "fourbar", "--duration", "0"], 2)])
def test_a_closed_stdout_keeps_the_exit_code_with_json(argv, expected):
    """Descriptor 1 closed from the start (`>&-`): the command ends as without --json (it exited 1 with a traceback)."""
    for flag in ([], ["--json"]):
        closed = ["sh", "-c", 'exec "$@" >&-', "sh", sys.executable, "-m", "pinstab.cli", *argv, *flag]
        completed = subprocess.run(closed, capture_output=True, text=True, timeout=120, check=False)
        assert completed.returncode == expected and "Traceback" not in completed.stderr, completed.stderr
