"""``pinstab run``: simulate a scene and report drift, energy and (with ``--reference``) the trajectory error."""

from __future__ import annotations

import argparse
import time
from typing import Any

from ...analysis import check_coordinates, check_reference, trajectory_error
from ...errors import PinstabError
from ...files import check_output
from ..clock import command_timings
from ..exits import EXIT_CODES
from ..options import run_options, scene_arguments, stream_argument
from ..running import ended, run_summary, simulate_scene
from .base import Command, register


def arguments(run: argparse.ArgumentParser) -> None:
    """The scene, the run options, ``--save``, ``--plot``, ``--reference``, ``--error-of``."""
    run.epilog = EXIT_CODES
    scene_arguments(run)
    run_options(run)
    stream_argument(run)
    run.add_argument("--save", metavar="FILE.npz", help="save the trajectory")
    run.add_argument(
        "--plot",
        metavar="FILE.png",
        help="chart drift, the energy budget (E - E(0) with the work of force elements, servo controls and impacts, "
        "and the energy error E - E(0) - W) and constraint forces",
    )
    run.add_argument(
        "--reference",
        metavar="exact|RUN.npz",
        help="report the trajectory error against the scene's exact motion (exact: fourbar, nfourbar) or a "
        "saved run of the same scene (--save of a finer or another method)",
    )
    run.add_argument(
        "--error-of",
        action="append",
        metavar="NAME",
        help="coordinate whose error --reference reports: a joint [rad or m], a frame's origin [m] or 'joints' "
        "(the largest joint error); repeat for several (default: the exact reference's crank, else joints)",
    )


def run(args: argparse.Namespace, add=None, scene=None) -> dict[str, Any]:
    """Simulate (``scene``: the scene already loaded, else loaded here), summarize (``add(scene, trajectory,
    result)`` adds figures), save and chart when asked."""
    from ...viz.plots import plot_trajectory

    began = time.perf_counter()
    if getattr(args, "stream", None):  # run takes --stream; servo, which runs through here, does not
        _check_stream(args)
    if args.save:
        check_output(args.save, ".npz", "trajectory")
    if args.plot:
        check_output(args.plot, ".png", "chart")
    reference = getattr(args, "reference", None)
    if reference is None and getattr(args, "error_of", None):
        raise PinstabError("--error-of names what --reference compares: give --reference exact or RUN.npz")
    scene, trajectory, failure = simulate_scene(
        args, None if reference is None else lambda scene: _check_reference(args, scene), scene
    )
    simulated = time.perf_counter()
    result = run_summary(args, trajectory)
    if add is not None:
        add(scene, trajectory, result)
    if reference is not None:
        trajectory.comparison = trajectory_error(trajectory, reference, args.error_of, scene)
        result["trajectory_error"] = trajectory.comparison.summary(trajectory.t)
    writing = time.perf_counter()
    if args.save:
        trajectory.save(args.save)
        result["saved"] = args.save
    if args.plot:
        plot_trajectory(trajectory, args.plot, scene)
        result["plot"] = args.plot
    result.update(command_timings(trajectory.info.timings, began, simulated, writing))  # the whole command's
    return ended(result, failure)


def _check_stream(args: argparse.Namespace) -> None:
    """Refuse with --stream the options that need the whole run in memory (naming what reads the file)."""
    options = (("--save", args.save), ("--plot", args.plot), ("--reference", args.reference))
    given = [flag for flag, value in options if value]
    if given:
        raise PinstabError(
            f"{', '.join(given)}: --stream keeps the run on disk, not in memory; the file {args.stream} is the saved "
            f"run: chart it with pinstab plot {args.stream} -o OUT.png, read it with Trajectory.load"
        )


def _check_reference(args: argparse.Namespace, scene) -> None:
    """Refuse --reference and --error-of before the run (a scene without an exact motion, a bad file, an
    unknown coordinate)."""
    check_reference(args.reference, scene)
    check_coordinates(scene.model, args.error_of or ())


register(Command("run", "simulate a scene and report drift and energy", arguments, run, simulates=True, order=3))
