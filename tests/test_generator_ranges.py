"""Every parameter of every generator has its own range, refused by the generator's and the parameter's name
(issue 34: ``--param height=1e6`` was refused as ``initial.q.root_joint``, a joint the user never wrote); the
range's boundaries generate a scene that runs."""

from __future__ import annotations

import math

import pytest
from fuzzing import cli

from pinstab.generators import (
    GENERATOR_PARAMETERS,
    MAX_LOOPS,
    MAX_STACK,
    MIN_LINK_LENGTH,
    MIN_MASS,
    MIN_RADIUS,
    generate,
)
from pinstab.units import MAX_COORDINATE, MAX_MAGNITUDE, MAX_RATE

# (generator, parameter): (a value out of its range, the range's boundaries); the ranges written out here from
# the reasons of generators.py's constants, not read back from the generators
RANGES: dict[tuple[str, str], tuple[float, list[float]]] = {
    ("nfourbar", "N"): (MAX_LOOPS + 1, [1, MAX_LOOPS]),
    ("nfourbar", "link_length"): (MAX_COORDINATE / 10 * 1.001, [MIN_LINK_LENGTH, MAX_COORDINATE / 10]),  # N = 10
    ("nfourbar", "link_mass"): (0.0, [MIN_MASS, MAX_MAGNITUDE]),
    ("incline", "theta"): (2.0, [0.0, math.pi / 2]),
    ("incline", "mu"): (11.0, [0.0, 10.0]),
    ("incline", "v_down"): (1e200, [-MAX_RATE, MAX_RATE]),
    ("incline", "v_across"): (-2e6, [-MAX_RATE, MAX_RATE]),
    ("sphere-spin", "v0"): (-1e7, [-MAX_RATE, MAX_RATE]),
    ("sphere-spin", "omega0"): (1e300, [-MAX_RATE, MAX_RATE]),
    ("sphere-spin", "mu"): (-0.1, [0.0, 10.0]),
    ("sphere-spin", "radius"): (1e9, [MIN_RADIUS, MAX_COORDINATE]),
    ("bouncing-ball", "height"): (1e6, [0.0, MAX_COORDINATE - 0.05]),  # its centre 0.05 m higher
    ("bouncing-ball", "restitution"): (1.5, [0.0, 1.0]),
    ("pinch", "mu"): (20.0, [0.0, 10.0]),
    ("pinch", "squeeze"): (2e6, [0.0, 1e6]),  # a joint-torque's range (forces.base.MAX_LOAD)
    ("pinch", "mass"): (1e-12, [MIN_MASS, MAX_MAGNITUDE]),
    ("painleve-rod", "mu"): (math.inf, [0.0, 10.0]),
    ("box-stack", "count"): (MAX_STACK + 1, [1, MAX_STACK]),
    ("box-stack", "mu"): (10.5, [0.0, 10.0]),
    ("box-stack", "drop"): (1.5, [-1.0, 1.0]),
}
BOUNDARIES = [(scene, name, value) for (scene, name), (_, values) in RANGES.items() for value in values]


def test_every_parameter_has_a_range_here() -> None:
    assert set(RANGES) == {(scene, name) for scene, names in GENERATOR_PARAMETERS.items() for name in names}


@pytest.mark.parametrize(("scene", "name"), list(RANGES))
def test_out_of_range_is_refused_by_name(scene: str, name: str) -> None:
    outcome = cli(["check", scene, f"--param={name}={RANGES[scene, name][0]!r}"])
    assert outcome.code == 2, outcome
    assert f"generator {scene}: parameter {name} must be" in outcome.message, outcome


@pytest.mark.parametrize(("scene", "name", "value"), BOUNDARIES)
def test_boundary_runs(scene: str, name: str, value: float) -> None:
    if (scene, name) == ("nfourbar", "N") and value == MAX_LOOPS:  # 2001 links: more memory than a test machine's
        assert len(generate(scene, {name: value})["closures"]) == MAX_LOOPS
        return
    # a spin of 1e6 rad/s turns the ball 1000 rad in a millisecond: a step of 0.1 rad (dt = 1e-7 s) resolves it
    # (at the default dt the event-driven run takes minutes for 0.01 s, its steps shrunk by the error control)
    steps = (
        ("--dt", "1e-7", "--duration", "1e-6") if (scene, name) == ("sphere-spin", "omega0") else ("--duration", "0.01")
    )
    outcome = cli(["run", scene, f"--param={name}={value!r}", *steps, "--quiet"])
    paradox = scene == "painleve-rod" and value > 4 / 3  # the generator's docstring: no contact mode, exit 5
    assert outcome.code == (5 if paradox else 0), outcome


def test_height_is_refused_as_a_parameter_not_a_joint() -> None:
    """The issue's example: ``pinstab run bouncing-ball --param height=1e6``."""
    outcome = cli(["run", "bouncing-ball", "--param", "height=1e6", "--quiet"])
    assert outcome.code == 2 and "parameter height" in outcome.message and "root_joint" not in outcome.message
