"""The catalogue of bad inputs (issue 13): each case is a command line, possibly on a scene file made from a
bundled one with a change and on files written for it (robot files, saved runs), and what it must end in: the
error class, the exit code and a phrase of the message. No traceback, no signal, each under 10 s.

Cases marked xfail are known bugs whose fix belongs to modules being changed elsewhere (strict: each turns
into a failure once fixed, to be unmarked then)."""

from __future__ import annotations

import io
import time
from dataclasses import dataclass

import numpy as np
import pytest

from conftest import ROBOTS
from pinstab import cli
from pinstab.errors import PinstabError


@dataclass(frozen=True)
class Case:
    """``argv`` ({scene} is replaced by the changed scene file, {tmp} by a temporary folder); the scene file is
    ``base`` with each (old, new) of ``changes`` replaced once (old must be present; {tmp} in new is replaced
    too); each (name, content) of ``files`` is written into {tmp} first (text or bytes)."""

    name: str
    argv: str
    error: str  # the PinstabError subclass, or "usage" for a command-line error (argparse)
    phrase: str
    base: str = "fourbar"
    changes: tuple[tuple[str, str], ...] = ()
    code: int = 2
    files: tuple[tuple[str, str | bytes], ...] = ()


FOURBAR_URDF = 'urdf = "urdf/fourbar.urdf"'
FOURBAR_URDF_TEXT = (ROBOTS / "urdf" / "fourbar.urdf").read_text()
BOX_URDF = 'urdf = "urdf/box.urdf"'
CRANK_MASS = '<mass value="0.5"/>'
CRANK_INERTIA = '<inertia ixx="5.625e-05" ixy="0" ixz="0" iyy="0.00166666666667" iyz="0" izz="0.00166666666667"/>'
BOX_QUATERNION = "0.0, 0.0, 0.0, 1.0]"
TINY_BENCH = "--serial --methods baumgarte --integrators rk4 --dts 1e-2 --peer-dts 1e-2 --mujoco-dts 1e-2"


def robot_file(name: str, argv: str, error: str, phrase: str, urdf: str, code: int = 2) -> Case:
    """A case on the four-bar scene whose robot is ``urdf`` (the text of a URDF file, written as {tmp}/bad.urdf)."""
    return Case(
        name,
        argv,
        error,
        phrase,
        changes=((FOURBAR_URDF, 'urdf = "{tmp}/bad.urdf"'),),
        code=code,
        files=(("bad.urdf", urdf),),
    )


def fourbar_urdf(old: str, new: str) -> str:
    """The four-bar's URDF with ``old`` replaced once by ``new`` (old must be present)."""
    assert old in FOURBAR_URDF_TEXT, old
    return FOURBAR_URDF_TEXT.replace(old, new, 1)


def chain_urdf(links: int) -> str:
    """A serial chain of ``links`` revolute joints, each link 10 cm and 1 kg."""
    inertial = (
        '<inertial><mass value="1"/><inertia ixx="1e-3" ixy="0" ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial>'
    )
    body = ['<robot name="chain"><link name="base"/>']
    for k in range(links):
        parent = "base" if k == 0 else f"l{k - 1}"
        body.append(f'<link name="l{k}">{inertial}</link>')
        body.append(
            f'<joint name="j{k}" type="continuous"><parent link="{parent}"/><child link="l{k}"/>'
            '<origin xyz="0.1 0 0"/><axis xyz="0 0 1"/></joint>'
        )
    return "".join([*body, "</robot>"])


def npz_bytes(**arrays: np.ndarray) -> bytes:
    """An NPZ archive of ``arrays`` (not a pinstab trajectory unless they make one)."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def npy_bytes() -> bytes:
    """A single NumPy array file (.npy), not an archive."""
    buffer = io.BytesIO()
    np.save(buffer, np.arange(3.0))
    return buffer.getvalue()


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
    Case("stability grid 1", "stability fourbar --grid 1", "PinstabError", "grid must be a whole number from 2 to 200"),
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
        "mu must be a number in [0, 10]",
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
    Case("grasp facets", "grasp allegro-sphere --facets 2", "PinstabError", "facets must be a whole number from 3 to"),
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
        code=5,  # contacts with no solution during the run: the run so far is kept
    ),
    Case(
        "control without QP",
        "run {scene} --duration 0.1",
        "GraspLostError",
        "would slide",
        base="allegro-lift",
        changes=(('margin = "0.2 N"', 'margin = "0.2 N"\ninternal_forces = false'),),
        code=5,  # contacts with no solution during the run: the run so far is kept
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
        code=5,  # after the start: the run stops with its samples kept (at t = 0 s it is bad input, 2)
    ),
    # -- contacts
    Case(
        "push outside the cone",
        "run {scene} --duration 0.01 --contacts held",
        "ContactInfeasibleError",
        "sticking contacts cannot hold",
        base="box-push",
        changes=(('"1 N"', '"6 N"'),),
        code=5,  # a result (contacts with no solution, the run so far kept), not bad input
    ),
    # -- numbers: gains, steps, durations, limits (run)
    Case("dt inf", "run fourbar --dt inf", "PinstabError", "dt must be a positive number, got inf"),
    Case("dt nan", "run fourbar --dt nan", "PinstabError", "dt must be a positive number, got nan"),
    Case("dt not a number", "run fourbar --dt abc", "usage", "invalid float value: 'abc'"),
    Case("duration inf", "run fourbar --duration inf", "PinstabError", "duration must be a positive number, got inf"),
    Case("drift limit nan", "run fourbar --drift-limit nan", "PinstabError", "drift_limit must be a positive number"),
    Case("record every negative", "run fourbar --record-every -3", "PinstabError", "got -3"),
    Case("record every fraction", "run fourbar --record-every 1.5", "usage", "invalid int value: '1.5'"),
    Case("gain nan", "run fourbar --kp nan", "PinstabError", "gain kp must be a finite number >= 0, got nan"),
    Case("gain kd inf", "run fourbar --kd inf", "PinstabError", "gain kd must be a finite number >= 0, got inf"),
    Case("too many steps", "run fourbar --dt 1e-9 --duration 100", "PinstabError", "exceed"),
    Case("too many samples", "run fourbar --dt 1e-4 --duration 1e6 --record-every 100", "PinstabError", "samples"),
    Case(
        "gain overflows strict",
        "run fourbar --kp 1e308 --strict",
        "UnstableGainsError",
        "rho(R(tau W)) = inf >= 1",
    ),
    Case(
        "gain overflows",
        "run fourbar --kp 1e308 --duration 0.01",
        "DivergenceError",
        "rho(R(tau W)) = inf >= 1",
        code=3,
    ),
    Case("damping overflows", "run fourbar --kd 1e308 --strict", "UnstableGainsError", "kd = 1e+308"),
    Case(
        "gain overflows semi-implicit euler",
        "run fourbar --kp 1e308 --integrator semi-implicit-euler --strict",
        "UnstableGainsError",
        "Stable for dt < 1.15e-155 s",
    ),
    Case(
        "pinocchio gain overflows",
        "run fourbar --method pinocchio --kp 1e308 --strict",
        "UnstableGainsError",
        "rho(R(tau W)) = inf >= 1",
    ),
    Case(
        "inertial gain overflows",
        "run fourbar --method mukharlyamov --variant inertial --kp 1e308 --kd 1 --strict",
        "UnstableGainsError",
        "rho(R(tau W)) = inf >= 1",
    ),
    Case(
        "steps overflow",
        "run fourbar --duration 1e308 --dt 1e-9",
        "PinstabError",
        "steps (duration 1e+308 s / dt 1e-09 s) exceed",
    ),
    Case("step subnormal", "run fourbar --dt 5e-324", "PinstabError", "s is below 1e-12 s"),
    # -- method and solver options on the wrong method, or out of range
    Case("kp with projection", "run fourbar --method projection --kp 10", "PinstabError", "takes no option 'kp'"),
    Case(
        "decay with baumgarte", "run fourbar --decay 0.5", "PinstabError", "method 'baumgarte' takes no option 'decay'"
    ),
    Case("kp with none", "run fourbar --method none --kp 10", "PinstabError", "method 'none' takes no option 'kp'"),
    Case(
        "decay one",
        "run fourbar --method mukharlyamov --decay 1",
        "PinstabError",
        "decay factor r must be in [0, 1), got 1.0",
    ),
    Case("decay nan", "run fourbar --method mukharlyamov --decay nan", "PinstabError", "got nan"),
    Case(
        "stiffness without damping",
        "run fourbar --method mukharlyamov --kp 100",
        "PinstabError",
        "give both stiffness (--kp) and damping (--kd)",
    ),
    Case("unknown variant", "run fourbar --method mukharlyamov --variant nope", "usage", "invalid choice: 'nope'"),
    Case("pinocchio mu", "run fourbar --solver pinocchio --pinocchio-mu -1", "PinstabError", "mu must be in [0, 1)"),
    Case("proxsuite eps", "run fourbar --solver proxsuite --proxsuite-eps 0", "PinstabError", "eps_abs must be in"),
    Case(
        "proxsuite iterations",
        "run fourbar --solver proxsuite --proxsuite-max-iter 0",
        "PinstabError",
        "max_iter must be an integer >= 1",
    ),
    Case(
        "option of another solver",
        "run fourbar --solver dense --proxsuite-eps 1e-9",
        "PinstabError",
        "solver 'dense' takes no option 'eps_abs'",
    ),
    Case(
        "projection tolerance",
        "run fourbar --method projection --projection-tolerance 0",
        "PinstabError",
        "tolerance must be > 0",
    ),
    Case(
        "projection iterations",
        "run fourbar --method projection --projection-iterations 0",
        "PinstabError",
        "max_iterations must be an integer >= 1",
    ),
    Case("cones on dense", "run box-push --contacts held --solver dense", "SolverError", "does not take cone rows"),
    Case("held options on event contacts", "run box-push --solver dense", "PinstabError", "give --contacts held"),
    Case("relation on pinocchio", "servo two-cars --method pinocchio", "SolverError", "not a frame closure"),
    # -- sizes
    Case("generator parameter negative", "check nfourbar --param N=-1", "SceneError", "parameter N must be an integer"),
    Case("generator parameter fraction", "check nfourbar --param N=1.5", "SceneError", "got 1.5"),
    Case("generator parameter boolean", "check nfourbar --param N=true", "SceneError", "got True"),
    Case("generator parameter too large", "check nfourbar --param N=1000000000", "SceneError", "must be at most"),
    # the largest generated model (nv = 2001) needs 1.3 GB a Data: a run holds three
    Case(
        "run beyond a given limit", "run nfourbar --param N=1000 --memory-limit 3GB", "MemoryBudgetError", "of memory"
    ),
    Case(
        "model beyond a given limit",
        "check nfourbar --param N=1000 --memory-limit 2GB",
        "MemoryBudgetError",
        "a model of 2001 velocities and 2001 joints needs about 2.61 GB",
    ),
    Case(
        "URDF of 1000 links",
        "check {tmp}/chain.toml --memory-limit 500MB",
        "MemoryBudgetError",
        "a model of 1000 velocities",
        files=(("chain.toml", '[robot]\nurdf = "chain.urdf"\n'), ("chain.urdf", chain_urdf(1000))),
    ),
    Case(
        "samples beyond memory",
        "run fourbar --duration 1000 --memory-limit 100MB",
        "MemoryBudgetError",
        "1,000,002 kept samples 192 MB",
    ),
    Case(
        "recording beyond memory",
        "record fourbar -o {tmp}/x.html --duration 1000 --fps 1 --memory-limit 100MB",
        "MemoryBudgetError",
        "limit of 100 MB",
    ),
    Case(
        "servo beyond memory",
        "servo two-cars --duration 10000 --memory-limit 1GB",
        "MemoryBudgetError",
        "keep fewer samples",
    ),
    Case("memory limit text", "check fourbar --memory-limit lots", "PinstabError", "'lots' is not a size"),
    Case("memory limit zero", "check fourbar --memory-limit 0", "PinstabError", "must be a positive, finite size"),
    Case("step below a picosecond", "run fourbar --dt 1e-13", "PinstabError", "is below 1e-12 s"),
    Case("unknown generator parameter", "check nfourbar --param M=3", "SceneError", "unknown parameter 'M'"),
    Case("generator length negative", "check nfourbar --param link_length=-1", "SceneError", "link_length"),
    Case("generator length nan", "check nfourbar --param link_length=nan", "SceneError", "link_length"),
    Case("generator parameter twice", "check nfourbar --param N=3 --param N=4", "SceneError", "twice"),
    Case(
        "grasp facets huge",
        "grasp allegro-sphere --facets 1000000000",
        "PinstabError",
        "facets must be a whole number from 3 to 32",
    ),
    Case("grasp facets 33", "grasp allegro-sphere --facets 33", "PinstabError", "got 33"),
    Case("grasp facets text", "grasp allegro-sphere --facets many", "usage", "invalid int value: 'many'"),
    # -- outputs
    Case("save into a folder", "run fourbar --save {tmp}", "PinstabError", "is a folder"),
    Case("save not writable", "run fourbar --save /proc/x.npz", "PinstabError", "not writable"),
    Case("save name too long", "run fourbar --save {tmp}/" + "a" * 300 + ".npz", "PinstabError", "too long"),
    Case("recording into a folder", "record fourbar -o {tmp}", "PinstabError", "is a folder"),
    Case("map not writable", "stability fourbar -o /proc/x.png", "PinstabError", "not writable"),
    Case("map suffix", "stability fourbar -o {tmp}/map.txt", "PinstabError", "the output must be a .png file"),
    Case("chart into a folder", "plot {tmp}/none.npz -o {tmp}", "PinstabError", "is a folder"),
    Case("chart suffix", "plot {tmp}/none.npz -o {tmp}/x.txt", "PinstabError", "the output must be a .png file"),
    # -- recordings
    Case(
        "recording fps huge",
        "record fourbar -o {tmp}/x.html --fps 1e9 --duration 0.1",
        "PinstabError",
        "more than the 100,000 a recording holds",
    ),
    Case("recording fps zero", "record fourbar -o {tmp}/x.html --fps 0 --duration 0.1", "PinstabError", "got 0.0"),
    Case("recording fps nan", "record fourbar -o {tmp}/x.html --fps nan --duration 0.1", "PinstabError", "got nan"),
    Case(
        "recording fps negative",
        "record fourbar -o {tmp}/x.html --fps -1 --duration 0.1",
        "PinstabError",
        "fps must be a positive number",
    ),
    Case("live fps huge", "record fourbar --live --fps 1e308 --duration 0.1", "PinstabError", "a recording holds"),
    # -- stability maps
    Case("map grid huge", "stability fourbar --grid 100000", "PinstabError", "from 2 to 200, got 100000"),
    Case("map steps zero", "stability fourbar --steps 0", "PinstabError", "steps must be a whole number at least 2"),
    Case("map too much work", "stability fourbar --steps 100000000", "PinstabError", "20,000,000 a map takes"),
    Case("map no perturbation", "stability fourbar --perturbation 0", "PinstabError", "perturbation must be a number"),
    Case("map perturbation nan", "stability fourbar --perturbation nan", "PinstabError", "got nan"),
    Case("map perturbation large", "stability fourbar --perturbation 2", "PinstabError", "at most 1"),
    Case("map dt from zero", "stability fourbar --dt-range 0 1", "PinstabError", "dt range must be two increasing"),
    Case("map dt nan", "stability fourbar --dt-range 1e-3 nan", "PinstabError", "got 0.001 nan"),
    Case("map gains negative", "stability fourbar --gain-range -1 10", "PinstabError", "gain range must be two"),
    Case("map gains reversed", "stability fourbar --gain-range 10 1", "PinstabError", "got 10.0 1.0"),
    Case("map method without gains", "stability fourbar --method projection", "usage", "invalid choice: 'projection'"),
    Case(
        "map of velocity constraints",
        "stability rolling-disk",
        "PinstabError",
        "violates no position constraint",
    ),
    Case("map of an unrealizable servo", "stability ring-on-rod", "ServoInfeasibleError", "cannot be realized"),
    Case("map of cones on dense", "stability box-push --grid 2 --steps 2", "SolverError", "does not take cone rows"),
    Case("element map unknown", "stability stiff-fourbar --element crank", "PinstabError", "elements with one"),
    Case("element map factors", "stability stiff-fourbar --factor-range 1 0", "PinstabError", "factor range must be"),
    Case(
        "element map gains", "stability stiff-fourbar --gain-range 1 10", "PinstabError", "not an option of an element"
    ),
    Case("gains map factors", "stability fourbar --factor-range 1 10", "PinstabError", "not an option of a gains map"),
    Case("gains map two schemes", "stability fourbar --integrator rk4 --integrator heun", "PinstabError", "takes one"),
    Case(
        "element map integrator twice",
        "stability stiff-fourbar --integrator rk4 --integrator rk4",
        "PinstabError",
        "each once, among those with a known stability function",
    ),
    Case(
        "element map too much work",
        "stability stiff-fourbar --steps 10000",
        "PinstabError",
        "maps of 40 x 40 runs of 10000 steps",
    ),
    # -- trajectory error (--reference, --error-of)
    Case("reference for a scene without one", "run fivebar --reference exact", "PinstabError", "scenes with one"),
    Case("reference missing", "run fourbar --reference {tmp}/none.npz", "PinstabError", "does not exist"),
    Case("reference a folder", "run fourbar --reference {tmp}", "PinstabError", "is a folder"),
    Case(
        "reference not a run",
        "run fourbar --reference {tmp}/run.npz",
        "PinstabError",
        "not a pinstab trajectory file",
        files=(("run.npz", "hello world\n"),),
    ),
    Case(
        "error of an unknown joint", "run fourbar --reference exact --error-of crank9", "PinstabError", "crank, coupler"
    ),
    Case("error of without reference", "run fourbar --error-of crank", "PinstabError", "give --reference"),
    Case(
        "exact reference under other gravity",
        "run {scene} --reference exact --duration 0.01",
        "PinstabError",
        "assumes gravity along -y",
        base="nfourbar",
        changes=(("[generator]", "gravity = [0.0, 0.0, -9.81]\n[generator]"),),
    ),
    # -- saved runs (plot)
    Case(
        "plot of a truncated archive",
        "plot {tmp}/run.npz -o {tmp}/x.png",
        "PinstabError",
        "not a pinstab trajectory file",
        files=(("run.npz", b"PK\x03\x04" + bytes(40)),),
    ),
    Case(
        "plot of a foreign archive",
        "plot {tmp}/run.npz -o {tmp}/x.png",
        "PinstabError",
        "it holds a, b",
        files=(("run.npz", npz_bytes(a=np.arange(3), b=np.ones(2))),),
    ),
    Case(
        "plot of a text file",
        "plot {tmp}/run.npz -o {tmp}/x.png",
        "PinstabError",
        "not a pinstab trajectory file",
        files=(("run.npz", "hello world\n"),),
    ),
    Case(
        "plot of an empty file",
        "plot {tmp}/run.npz -o {tmp}/x.png",
        "PinstabError",
        "not a pinstab trajectory file",
        files=(("run.npz", ""),),
    ),
    Case(
        "plot of an array file",
        "plot {tmp}/run.npz -o {tmp}/x.png",
        "PinstabError",
        "not a pinstab trajectory file",
        files=(("run.npz", npy_bytes()),),
    ),
    Case("plot of a folder", "plot {tmp} -o {tmp}/x.png", "PinstabError", "is a folder"),
    # -- benchmarks (refused before the sweep, or after a sweep of a few tiny runs)
    Case("bench duration zero", f"bench fourbar -o {{tmp}}/b --duration 0 {TINY_BENCH}", "PinstabError", "got 0.0"),
    Case(
        "bench duration nan",
        f"bench fourbar -o {{tmp}}/b --duration nan {TINY_BENCH}",
        "PinstabError",
        "duration must be a positive number of seconds, got nan",
    ),
    Case(
        "bench duration huge",
        f"bench fourbar -o {{tmp}}/b --duration 1e308 {TINY_BENCH}",
        "PinstabError",
        "a run takes",
    ),
    Case("bench step inf", "bench fourbar -o {tmp}/b --dts inf", "PinstabError", "step inf s of baumgarte"),
    Case("bench step subnormal", "bench fourbar -o {tmp}/b --dts 5e-324", "PinstabError", "makes inf steps"),
    Case("bench step longer", "bench fourbar -o {tmp}/b --dts 10", "PinstabError", "is longer than the duration 2 s"),
    Case(
        "bench scheduler address",
        "bench fourbar -o {tmp}/b --scheduler nonsense --duration 0.01",
        "PinstabError",
        "cannot reach the Dask scheduler 'nonsense'",
    ),
    Case(
        "bench tolerance negative",
        f"bench fourbar -o {{tmp}}/b --duration 0.01 --tolerance -1 {TINY_BENCH}",
        "PinstabError",
        "tolerance must be a positive number",
    ),
    Case(
        "bench output is a file",
        "bench fourbar -o {tmp}/b",
        "PinstabError",
        "cannot create the output folder",
        files=(("b", "a file\n"),),
    ),
    Case(
        "bench output under a file",
        f"bench fourbar -o {{tmp}}/b/c --duration 0.01 {TINY_BENCH}",
        "PinstabError",
        "b/c",
        files=(("b", "a file\n"),),
    ),
    Case("bench unknown method", "bench fourbar -o {tmp}/b --methods magic", "usage", "invalid choice: 'magic'"),
    # -- robot files
    robot_file(
        "link mass negative",
        "check {scene}",
        "SceneError",
        "mass -0.5 kg is negative",
        fourbar_urdf(CRANK_MASS, '<mass value="-0.5"/>'),
    ),
    robot_file(
        "link mass nan",
        "check {scene}",
        "SceneError",
        "mass 'nan' is not a finite number",
        fourbar_urdf(CRANK_MASS, '<mass value="nan"/>'),
    ),
    robot_file(
        "link mass text", "check {scene}", "SceneError", "'heavy'", fourbar_urdf(CRANK_MASS, '<mass value="heavy"/>')
    ),
    robot_file(
        "inertia not positive",
        "check {scene}",
        "SceneError",
        "inertia is not positive semidefinite",
        fourbar_urdf(CRANK_INERTIA, CRANK_INERTIA.replace('iyy="0.00166666666667"', 'iyy="-0.00166666666667"')),
    ),
    robot_file(
        "inertia triangle",
        "check {scene}",
        "SceneError",
        "violates the triangle inequality",
        fourbar_urdf(CRANK_INERTIA, '<inertia ixx="1" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>'),
    ),
    robot_file("URDF not XML", "check {scene}", "SceneError", "the URDF cannot be read", "this is not xml at all"),
    robot_file("URDF empty", "check {scene}", "SceneError", "the URDF cannot be read", ""),
    robot_file(
        "URDF without robot",
        "check {scene}",
        "SceneError",
        "the URDF cannot be read",
        '<?xml version="1.0"?><nothing/>',
    ),
    robot_file(
        "URDF joint type",
        "check {scene}",
        "SceneError",
        "the URDF cannot be read",
        fourbar_urdf('type="revolute"', 'type="twisty"'),
    ),
    robot_file(
        "URDF unicode joint",
        "check {scene}",
        "SceneError",
        "valid joints: coupler, kurbel\u00e9\u4e2d, rocker",
        fourbar_urdf('<joint name="crank"', '<joint name="kurbel\u00e9\u4e2d"'),
    ),
    robot_file(
        "URDF parent missing",
        "check {scene}",
        "SceneError",
        "'nowhere'",
        fourbar_urdf('<parent link="crank"/>', '<parent link="nowhere"/>'),
    ),
    robot_file(
        "URDF joint twice",
        "check {scene}",
        "SceneError",
        "joint 'crank' is defined twice",
        fourbar_urdf('<joint name="rocker"', '<joint name="crank"'),
    ),
    robot_file(
        "URDF zero axis",
        "check {scene}",
        "SceneError",
        "axis",
        fourbar_urdf('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'),
    ),
    robot_file(
        "mesh missing",
        "record {scene} -o {tmp}/x.html --duration 0.01",
        "SceneError",
        "meshes/nothing.stl could not be found",
        fourbar_urdf('<cylinder radius="0.015" length="0.2"/>', '<mesh filename="meshes/nothing.stl"/>'),
    ),
    Case(
        "link named world",
        "check {scene}",
        "SceneError",
        "shadows pinstab's world frame",
        base="box-push",
        changes=((BOX_URDF, 'urdf = "{tmp}/world.urdf"'),),
        files=(
            ("world.urdf", (ROBOTS / "urdf" / "box.urdf").read_text().replace('link name="box"', 'link name="world"')),
        ),
    ),
    Case(
        "free flyer zero quaternion",
        "check {scene}",
        "SceneError",
        "is not a unit quaternion",
        base="box-push",
        changes=((BOX_QUATERNION, "0.0, 0.0, 0.0, 0.0]"),),
    ),
    Case(
        "free flyer short",
        "check {scene}",
        "SceneError",
        "must be a list of 7 numbers",
        base="box-push",
        changes=(("0.025, " + BOX_QUATERNION, "0.025, 1.0]"),),
    ),
    # -- contacts, rolling, closures
    Case(
        "contact mu negative",
        "check {scene}",
        "SceneError",
        "mu must be a number in [0, 10]",
        base="box-push",
        changes=(("\nmu = 0.5", "\nmu = -0.5"),),
    ),
    Case(
        "contact facets without mu",
        "check {scene}",
        "SceneError",
        "'facets' linearizes a friction cone; give 'mu' too",
        base="box-push",
        changes=(("\nmu = 0.5", "\nfacets = 8"),),
    ),
    Case(
        "contact names repeated",
        "check {scene}",
        "SceneError",
        "repeated: front-left",
        base="box-push",
        changes=(('name = "front-right"', 'name = "front-left"'),),
    ),
    Case(
        "push infinite",
        "check {scene}",
        "SceneError",
        "'1e309 N' is not finite",
        base="box-push",
        changes=(('force = ["1 N"', 'force = ["1e309 N"'),),
    ),
    Case(
        "disk radius zero",
        "check {scene}",
        "SceneError",
        "contact 'floor'.radius must be > 0",
        base="rolling-disk",
        changes=(("radius = 0.3", "radius = 0.0"),),
    ),
    Case(
        "disk axis zero",
        "check {scene}",
        "SceneError",
        "contact 'floor'.axis must be a non-zero vector",
        base="rolling-disk",
        changes=(("axis = [0.0, 1.0, 0.0]", "axis = [0.0, 0.0, 0.0]"),),
    ),
    Case(
        "disk lying flat",
        "run {scene} --duration 0.01",
        "SceneError",
        "the disk lies flat on the plane",
        base="rolling-disk",
        changes=(("axis = [0.0, 1.0, 0.0]", "axis = [0.0, 0.0, 1.0]"),),
    ),
    Case(
        "rolling mu negative",
        "check {scene}",
        "SceneError",
        "contact 'tip'.mu must be a number in [0, 10]",
        base="finger-rolling",
        changes=(("mu = 0.8", "mu = -1"),),
    ),
    Case(
        "rolling model",
        "check {scene}",
        "SceneError",
        "a rolling contact's model is one of",
        base="finger-rolling",
        changes=(('model = "soft-finger"', 'model = "hard"'),),
    ),
    Case(
        "rolling unknown object",
        "check {scene}",
        "SceneError",
        "'bowl' is not an object of the scene",
        base="finger-rolling",
        changes=(('object = "ball"', 'object = "bowl"'),),
    ),
    Case(
        "torque table backwards",
        "check {scene}",
        "SceneError",
        "times must be strictly increasing",
        base="finger-rolling",
        changes=(("table = [[0.0, 0.07212], [1.0", "table = [[1.0, 0.07212], [0.0"),),
    ),
    Case(
        "closure on one body",
        "check {scene}",
        "SceneError",
        "both frames are on the same rigid body",
        changes=(('frame_b = "rocker"', 'frame_b = "coupler"'),),
    ),
    Case(
        "closure cannot assemble",
        "check {scene}",
        "AssemblyError",
        "the closures cannot be met",
        changes=(("offset_b = [0.5, 0.0, 0.0]", "offset_b = [5.0, 0.0, 0.0]"),),
    ),
    # -- servos
    Case(
        "servo limits reversed",
        "servo {scene} --duration 0.05",
        "SceneError",
        "every lower bound must be below its upper bound",
        base="two-cars",
        changes=(('joints = ["x1"]', 'joints = ["x1"]\nlower = [2.0]\nupper = [-2.0]'),),
    ),
    Case(
        "servo limit nan",
        "servo {scene} --duration 0.05",
        "SceneError",
        "actuation.lower has a non-finite entry",
        base="two-cars",
        changes=(('joints = ["x1"]', 'joints = ["x1"]\nlower = [nan]\nupper = [2.0]'),),
    ),
    Case(
        "servo limits length",
        "servo {scene} --duration 0.05",
        "SceneError",
        "actuation.lower must be a list of 1 numbers",
        base="two-cars",
        changes=(('joints = ["x1"]', 'joints = ["x1"]\nlower = [-1.0, -2.0]\nupper = [2.0]'),),
    ),
    Case(
        "servo zero relation",
        "servo {scene} --duration 0.05",
        "SceneError",
        "every coefficient is zero",
        base="two-cars",
        changes=(("joints = { x1 = 1.0 }", "joints = { x1 = 0.0 }"),),
    ),
    Case(
        "servo frequency unit",
        "servo {scene} --duration 0.05",
        "SceneError",
        "is not a unit of angular-velocity",
        base="two-cars",
        changes=(('omega = "1 rad/s"', 'omega = "1 m"'),),
    ),
    Case(
        "unknown trajectory kind",
        "servo {scene} --duration 0.05",
        "SceneError",
        "unknown trajectory kind 'bezier'; valid kinds: cubic-spline, minimum-jerk, polynomial, sinusoid",
        base="two-cars",
        changes=(('sine = { amplitude = 0.8, omega = "1 rad/s" }', 'target = { kind = "bezier" }'),),
    ),
    Case(
        "spline times unsorted",
        "servo {scene} --duration 0.05",
        "WaypointError",
        "times must increase strictly: times[2] = 0.5 s after times[1] = 1 s",
        base="two-cars",
        changes=(
            (
                'sine = { amplitude = 0.8, omega = "1 rad/s" }',
                'target = { kind = "cubic-spline", times = [0, 1, 0.5], values = [0, 1, 2] }',
            ),
        ),
    ),
    Case(
        "actuated twice",
        "servo {scene} --duration 0.05",
        "SceneError",
        "distinct joint names",
        base="two-cars",
        changes=(('joints = ["x1"]', 'joints = ["x1", "x1"]'),),
    ),
    Case(
        "gravity beyond reason",
        "check {scene}",
        "SceneError",
        "is longer than 1e+06 m/s^2",
        changes=(("gravity = [0.0, -9.81, 0.0]", "gravity = [0.0, -1e308, 0.0]"),),
    ),
    Case(
        "initial angle beyond reason",
        "check {scene}",
        "SceneError",
        "initial.q.crank: 1e+300 is beyond 1e+06 m or rad",
        changes=(("q = { crank = 1.0", "q = { crank = 1e300"),),
    ),
    Case("save under a name too long", "run fourbar --save {tmp}/" + "d" * 300 + "/x.npz", "PinstabError", "too long"),
]


def run_case(case: Case, tmp_path, capsys) -> tuple[int, str, str]:
    """(exit code, error class name, stderr) of the case's command."""
    for name, content in case.files:
        target = tmp_path / name
        target.write_bytes(content) if isinstance(content, bytes) else target.write_text(content)
    scene = tmp_path / f"{case.base}-changed.toml"
    if case.changes:
        text = (ROBOTS / f"{case.base}.toml").read_text()
        for old, new in case.changes:
            assert old in text, f"case {case.name!r}: {old!r} is not in {case.base}.toml"
            text = text.replace(old, new.replace("{tmp}", str(tmp_path)), 1)
        text = text.replace('urdf = "urdf/', f'urdf = "{ROBOTS}/urdf/')
        scene.write_text(text)
    argv = case.argv.format(scene=scene, tmp=tmp_path).split()
    seen: list[str] = []
    original = cli.dispatch._fail

    def record(exc: PinstabError, args, *rest) -> None:
        seen.append(type(exc).__name__)
        original(exc, args, *rest)

    cli.dispatch._fail = record
    try:
        code = cli.main([*argv, *(["--quiet"] if argv[0] in ("run", "record", "servo") else [])])
    except SystemExit as exit_:
        code, seen = int(exit_.code), ["usage"]
    finally:
        cli.dispatch._fail = original
    return code, (seen[0] if seen else ""), capsys.readouterr().err


def test_cases_are_distinct():
    names = [case.name for case in CASES]
    inputs = [(case.argv, case.base, case.changes, case.files) for case in CASES]
    assert len(set(names)) == len(names) and len(set(inputs)) == len(inputs)
    assert len(CASES) >= 80


@pytest.mark.parametrize("case", CASES, ids=[case.name for case in CASES])
def test_bad_input_ends_in_its_named_error(case, tmp_path, capsys):
    start = time.perf_counter()
    code, error, err = run_case(case, tmp_path, capsys)
    assert (code, error) == (case.code, case.error), err
    assert case.phrase in err and "Traceback" not in err
    assert time.perf_counter() - start < 10.0
