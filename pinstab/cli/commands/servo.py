"""``pinstab servo``: realize a scene's prescribed constraints (controls, constraint error, reactions)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from ...errors import SceneError
from ..exits import EXIT_CODES
from ..options import DEFAULT_METHOD, assembly_tolerance, run_options, scene_arguments, scene_options
from .base import Command, register
from .check import servo_at_start
from .run import run


def arguments(servo: argparse.ArgumentParser) -> None:
    """The scene, the run options, ``--check``, ``--save``, ``--plot``."""
    servo.epilog = EXIT_CODES
    scene_arguments(servo)
    run_options(servo)
    servo.add_argument(
        "--check", action="store_true", help="only check at the start that the controls can realize them"
    )
    servo.add_argument("--save", metavar="FILE.npz", help="save the trajectory")
    servo.add_argument(
        "--plot",
        metavar="FILE.png",
        help="chart drift, the energy budget (E - E(0) with the work of the controls, force elements and impacts, "
        "and the energy error E - E(0) - W), constraint forces and controls",
    )


def servo(args: argparse.Namespace) -> dict[str, Any]:
    from ...scene import load_scene
    from ...simulate.limits import held_limits

    scene = load_scene(args.scene, **scene_options(args))
    if not any(c.prescribed for c in scene.constraints):
        raise SceneError(f"scene {scene.name} has no prescribed constraints ([[servos]]) to realize")
    if args.check:
        held_limits(scene, scene.q0, not args.ignore_limits)  # the start that the run would refuse
        return {"scene": scene.name, **servo_at_start(scene, args.method or DEFAULT_METHOD, assembly_tolerance(args))}
    return run(args, _add_reactions, scene)


def _add_reactions(scene, trajectory, result: dict[str, Any]) -> None:
    """The largest reaction of the real constraints over the run [N, N m] (prescribed rows have none)."""
    reactions = trajectory.multipliers[:, ~scene.constraint_set.prescribed_mask]
    result["max_reaction"] = float(np.nanmax(np.abs(reactions))) if reactions.size else 0.0


register(
    Command(
        "servo",
        "realize a scene's prescribed constraints: controls, constraint error, reactions",
        arguments,
        servo,
        simulates=True,
        order=2,
    )
)
