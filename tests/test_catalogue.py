"""The catalogue of bad inputs (issue 13): each case is a command line, possibly on a scene file made from a
bundled one with a change, and what it must end in: the error class, the exit code and a phrase of the
message. No traceback, no signal, each under 10 s."""

from __future__ import annotations

import time
from dataclasses import dataclass

import pytest

from conftest import ROBOTS
from pinstab import cli
from pinstab.errors import PinstabError


@dataclass(frozen=True)
class Case:
    """``argv`` ({scene} is replaced by the changed scene file, {tmp} by a temporary folder); the scene file is
    ``base`` with each (old, new) of ``changes`` replaced once (old must be present)."""

    name: str
    argv: str
    error: str  # the PinstabError subclass, or "usage" for a command-line error (argparse)
    phrase: str
    base: str = "fourbar"
    changes: tuple[tuple[str, str], ...] = ()
    code: int = 2


FOURBAR_URDF = 'urdf = "urdf/fourbar.urdf"'

CASES = [
    # -- command line: numbers and choices
    Case("dt zero", "run fourbar --dt 0", "PinstabError", "dt must be a positive number, got 0.0"),
    Case("dt negative", "run fourbar --dt -1", "PinstabError", "dt must be a positive number"),
    Case("duration zero", "run fourbar --duration 0", "PinstabError", "duration must be a positive number"),
    Case("duration nan", "run fourbar --duration nan", "PinstabError", "duration must be a positive number, got nan"),
    Case("record every zero", "run fourbar --record-every 0", "PinstabError", "record_every must be a whole number"),
    Case("negative gain", "run fourbar --kp -1", "PinstabError", "gain kp must be a finite number >= 0"),
    Case("drift limit negative", "run fourbar --drift-limit -1", "PinstabError", "drift_limit must be a positive"),
    Case("unknown method", "run fourbar --method magic", "usage", "invalid choice: 'magic'"),
    Case("unknown integrator", "run fourbar --integrator magic", "usage", "invalid choice: 'magic'"),
    Case("unknown solver", "run fourbar --solver magic", "usage", "invalid choice: 'magic'"),
    Case("stability grid 1", "stability fourbar --grid 1", "PinstabError", "grid and steps must be at least 2"),
    Case("bench negative dt", "bench fourbar -o {tmp}/b --dts -1", "PinstabError", "steps must be positive"),
    Case("generator parameter zero", "check nfourbar --param N=0", "SceneError", "parameter N must be an integer >= 1"),
    Case("generator parameter text", "check nfourbar --param N=abc", "SceneError", "parameter N must be an integer"),
    Case("parameter without generator", "check fourbar --param N=3", "SceneError", "has no [generator] to take them"),
    Case("parameter without value", "check nfourbar --param N", "SceneError", "--param expects NAME=VALUE"),
    # -- outputs, refused before the run
    Case("save suffix", "run fourbar --save {tmp}/x.txt", "PinstabError", "the output must be a .npz file"),
    Case("save folder missing", "run fourbar --save {tmp}/no/x.npz", "PinstabError", "does not exist"),
    Case("plot suffix", "run fourbar --plot {tmp}/x.npz", "PinstabError", "the output must be a .png file"),
    Case("record without output", "record fourbar", "PinstabError", "give -o OUT.html for a recording"),
    Case("plot of a missing run", "plot {tmp}/none.npz -o {tmp}/x.png", "PinstabError", "none.npz"),
    # -- scenes by name and file
    Case("unknown scene", "run nope", "SceneError", "no scene named 'nope'"),
    Case("missing scene file", "run {tmp}/missing.toml", "SceneError", "does not exist"),
    Case("not TOML", "check {scene}", "SceneError", "not valid TOML", changes=(("[robot]", "[robot"),)),
    Case("unknown top key", "check {scene}", "SceneError", "unknown key 'robto'", changes=(("[robot]", "[robto]"),)),
    Case(
        "missing URDF",
        "check {scene}",
        "SceneError",
        "does not exist",
        changes=((FOURBAR_URDF, 'urdf = "urdf/nothing.urdf"'),),
    ),
    Case(
        "unknown closure kind",
        "check {scene}",
        "SceneError",
        "is not a constraint kind",
        changes=(('kind = "planar-point"', 'kind = "hinge"'),),
    ),
    Case(
        "unknown frame",
        "check {scene}",
        "SceneError",
        "unknown frame 'coupler2'",
        changes=(('frame_a = "coupler"', 'frame_a = "coupler2"'),),
    ),
    Case(
        "unknown plane",
        "check {scene}",
        "SceneError",
        "'plane' must be one of",
        changes=(('plane = "xy"', 'plane = "xw"'),),
    ),
    Case(
        "bad unit",
        "check {scene}",
        "SceneError",
        "is not a unit of",
        changes=(("gravity = [0.0, -9.81, 0.0]", 'gravity = [0.0, "9.81 N", 0.0]'),),
    ),
    Case(
        "gravity length",
        "check {scene}",
        "SceneError",
        "gravity must be a list of 3",
        changes=(("gravity = [0.0, -9.81, 0.0]", "gravity = [0.0, 9.81]"),),
    ),
    Case(
        "unknown joint in q",
        "check {scene}",
        "SceneError",
        "unknown joint 'crank2'",
        changes=(("q = { crank", "q = { crank2 = 0.1, crank"),),
    ),
    Case(
        "unknown force kind",
        "check {scene}",
        "SceneError",
        "is not a force kind",
        changes=(("[initial]", '[[forces]]\nkind = "motor"\n[initial]'),),
    ),
    # -- objects, grasp contacts, holds
    Case(
        "object unknown shape",
        "check {scene}",
        "SceneError",
        "unknown shape 'cone'",
        base="allegro-sphere",
        changes=(('shape = "sphere"', 'shape = "cone"'),),
    ),
    Case(
        "object zero radius",
        "check {scene}",
        "SceneError",
        "radius must be > 0",
        base="allegro-sphere",
        changes=(('radius = "35 mm"', 'radius = "0 mm"'),),
    ),
    Case(
        "object mass and density",
        "check {scene}",
        "SceneError",
        "give exactly one of 'density'",
        base="allegro-sphere",
        changes=(('mass = "100 g"', 'mass = "100 g"\ndensity = 1000'),),
    ),
    Case(
        "grasp unknown finger",
        "grasp {scene}",
        "SceneError",
        "unknown frame 'link_3_tip'",
        base="allegro-sphere",
        changes=(('finger = "link_3.0_tip"', 'finger = "link_3_tip"'),),
    ),
    Case(
        "grasp on a robot body",
        "grasp {scene}",
        "SceneError",
        "is a body of the robot, not an object",
        base="allegro-sphere",
        changes=(('object = "ball"', 'object = "link_2.0"'),),
    ),
    Case(
        "grasp mu negative",
        "grasp {scene}",
        "SceneError",
        "mu must be >= 0",
        base="allegro-sphere",
        changes=(('"12 mm"\nmu = 0.8', '"12 mm"\nmu = -0.8'),),
    ),
    Case(
        "grasp radius zero",
        "grasp {scene}",
        "SceneError",
        "radius must be > 0",
        base="allegro-sphere",
        changes=(('radius = "12 mm"', 'radius = "0 mm"'),),
    ),
    Case(
        "grasp unreachable",
        "grasp {scene}",
        "SceneError",
        "cannot reach object 'ball'",
        base="allegro-sphere",
        changes=(("position = [0.0916", "position = [0.3916"),),
    ),
    Case(
        "grasp unknown model",
        "grasp {scene}",
        "SceneError",
        "unknown contact model 'sticky'",
        base="allegro-sphere",
        changes=(('model = "point-friction"', 'model = "sticky"'),),
    ),
    Case("grasp without contacts", "grasp fourbar", "PinstabError", "has no grasp contacts"),
    Case("grasp facets", "grasp allegro-sphere --facets 2", "PinstabError", "facets must be a whole number >= 3"),
    Case(
        "hold unknown object",
        "check {scene}",
        "SceneError",
        "'cube' is not an object",
        base="allegro-sphere",
        changes=(('object = "ball"\nsqueeze', 'object = "cube"\nsqueeze'),),
    ),
    Case(
        "grasp lost",
        "run {scene} --duration 0.2",
        "GraspLostError",
        "grasp lost at t =",
        base="allegro-sphere",
        changes=(('"0.2 N"', '"5 N"'),),
    ),
    Case(
        "control without QP",
        "run {scene} --duration 0.1",
        "GraspLostError",
        "would slide",
        base="allegro-lift",
        changes=(('margin = "0.2 N"', 'margin = "0.2 N"\ninternal_forces = false'),),
    ),
    # -- servos
    Case("servo without servos", "servo fourbar", "SceneError", "has no prescribed constraints"),
    Case("servo unrealizable", "servo ring-on-rod --check", "ServoInfeasibleError", "no control reaches the direction"),
    Case(
        "servo without actuation",
        "check {scene}",
        "SceneError",
        "add an [actuation] table",
        base="two-cars",
        changes=(('[actuation]\njoints = ["x1"]', ""),),
    ),
    Case(
        "actuation unknown joint",
        "check {scene}",
        "SceneError",
        "unknown joint 'x3'",
        base="two-cars",
        changes=(('joints = ["x1"]', 'joints = ["x3"]'),),
    ),
    Case(
        "servo limits",
        "servo {scene} --duration 2",
        "ServoInfeasibleError",
        "within the control limits",
        base="two-cars",
        changes=(('joints = ["x1"]', 'joints = ["x1"]\nlower = [-2.0]\nupper = [2.0]'),),
    ),
    # -- contacts
    Case(
        "push outside the cone",
        "run {scene} --duration 0.01",
        "ContactInfeasibleError",
        "sticking contacts cannot hold",
        base="box-push",
        changes=(('"1 N"', '"6 N"'),),
    ),
]


def run_case(case: Case, tmp_path, capsys) -> tuple[int, str, str]:
    """(exit code, error class name, stderr) of the case's command."""
    scene = tmp_path / f"{case.base}-changed.toml"
    if case.changes:
        text = (ROBOTS / f"{case.base}.toml").read_text()
        for old, new in case.changes:
            assert old in text, f"case {case.name!r}: {old!r} is not in {case.base}.toml"
            text = text.replace(old, new, 1)
        text = text.replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
        scene.write_text(text)
    argv = case.argv.format(scene=scene, tmp=tmp_path).split()
    seen: list[str] = []
    original = cli._fail

    def record(exc: PinstabError, args) -> None:
        seen.append(type(exc).__name__)
        original(exc, args)

    cli._fail = record
    try:
        code = cli.main([*argv, *(["--quiet"] if argv[0] in ("run", "record", "servo") else [])])
    except SystemExit as exit_:
        code, seen = int(exit_.code), ["usage"]
    finally:
        cli._fail = original
    return code, (seen[0] if seen else ""), capsys.readouterr().err


@pytest.mark.parametrize("case", CASES, ids=[case.name for case in CASES])
def test_bad_input_ends_in_its_named_error(case, tmp_path, capsys):
    start = time.perf_counter()
    code, error, err = run_case(case, tmp_path, capsys)
    assert (code, error) == (case.code, case.error), err
    assert case.phrase in err and "Traceback" not in err
    assert time.perf_counter() - start < 10.0
