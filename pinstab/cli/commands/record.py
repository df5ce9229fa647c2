"""``pinstab record``: simulate and write a standalone HTML recording, or stream it live."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from ...errors import PinstabError
from ...files import check_output
from ..exits import EXIT_CODES
from ..options import output_argument, run_options, scene_arguments
from ..output import emit
from ..running import ended, run_summary, simulate_scene
from .base import Command, register

if TYPE_CHECKING:
    from ...model import ConstrainedModel
    from ...trajectory import Trajectory


def arguments(record: argparse.ArgumentParser) -> None:
    """The scene, the run options, ``-o``, ``--fps``, ``--live``."""
    record.epilog = EXIT_CODES
    scene_arguments(record)
    run_options(record)
    output_argument(record, "OUT.html", "the recording to write")
    record.add_argument("--fps", type=float, default=30.0, help="frames per second of the recording (default: 30)")
    record.add_argument(
        "--live",
        action="store_true",
        help="stream to a meshcat server on 127.0.0.1 (its URL on stderr), replaying the motion until Ctrl-C "
        "(exit 130) or SIGTERM (exit 143); the run's figures are printed first",
    )
    record.add_argument(
        "--from",
        dest="run_file",
        metavar="RUN.npz|RUN.h5",
        help="record a saved (--save) or streamed (--stream) run of the scene instead of simulating it",
    )


def record(args: argparse.Namespace) -> dict[str, Any]:
    import time

    from ...model import ConstrainedModel
    from ...viz.recording import check_frames, write_recording

    if not args.live and not args.output:
        raise PinstabError("record: give -o OUT.html for a recording, or --live to stream to a meshcat viewer")
    if args.output:
        check_output(args.output, ".html", "recording")
    start = time.perf_counter()
    if args.run_file:
        scene, trajectory, failure = _saved_run(args)
    else:
        check_frames(args.duration, args.fps)
        scene, trajectory, failure = simulate_scene(args)
    model = ConstrainedModel(scene)
    result = run_summary(args, trajectory)
    if args.output:
        recording = write_recording(model, trajectory, args.output, fps=args.fps)
        result.update(
            recording=str(recording.path),
            size_bytes=recording.size_bytes,
            frames=recording.frames,
            fps=recording.fps,
            force_scale=recording.force_scale,
        )
    result["record_wall_s"] = time.perf_counter() - start
    if args.live:
        _serve(args, model, trajectory, result, failure)
    return ended(result, failure)


def _serve(
    args: argparse.Namespace,
    model: ConstrainedModel,
    trajectory: Trajectory,
    result: dict[str, Any],
    failure: PinstabError | None,
) -> None:
    """``--live``: the viewer started, the run's figures (with ``live_url``) and its failure printed, then its motion
    replayed in the viewer until the process is interrupted (Ctrl-C: exit 130, SIGTERM: 143); never returns."""
    from ...viz.recording import live_viewer, play_live

    viewer = live_viewer()
    result["live_url"] = viewer.url()
    if failure is not None:
        result["error"] = str(failure)
        print(f"pinstab record: error: {failure}", file=sys.stderr)
    emit(result, args.json)
    play_live(model, trajectory, fps=args.fps, viewer=viewer, hold=True)


def _saved_run(args: argparse.Namespace):
    """(scene, trajectory, None) of ``--from``: the run file read whole, checked against the scene."""
    from ...scene import load_scene
    from ...trajectory import Trajectory
    from ..options import scene_options

    scene = load_scene(args.scene, **scene_options(args))
    trajectory = Trajectory.load(args.run_file)
    if trajectory.q.shape[1] != scene.model.nq:
        raise PinstabError(
            f"{args.run_file}: a run of scene {trajectory.info.scene} with {trajectory.q.shape[1]} coordinates, "
            f"scene {scene.name} has {scene.model.nq}: give the scene (and --param) the run was made with"
        )
    args.duration = float(trajectory.t[-1])
    return scene, trajectory, None


register(
    Command(
        "record",
        "simulate and write a standalone HTML recording (or stream it live)",
        arguments,
        record,
        simulates=True,
        order=4,
    )
)
