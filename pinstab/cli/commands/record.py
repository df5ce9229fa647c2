"""``pinstab record``: simulate and write a standalone HTML recording, or stream it live."""

from __future__ import annotations

import argparse
from typing import Any

from ...errors import PinstabError
from ...files import check_output
from ..exits import EXIT_CODES
from ..options import run_options, scene_arguments
from ..running import ended, run_summary, simulate_scene
from .base import Command, register


def arguments(record: argparse.ArgumentParser) -> None:
    """The scene, the run options, ``-o``, ``--fps``, ``--live``."""
    record.epilog = EXIT_CODES
    scene_arguments(record)
    run_options(record)
    record.add_argument("-o", "--output", metavar="OUT.html", help="the recording to write")
    record.add_argument("--fps", type=float, default=30.0, help="frames per second of the recording (default: 30)")
    record.add_argument("--live", action="store_true", help="stream to a meshcat server on 127.0.0.1 instead")
    record.add_argument(
        "--from",
        dest="run_file",
        metavar="RUN.npz|RUN.h5",
        help="record a saved (--save) or streamed (--stream) run of the scene instead of simulating it",
    )


def record(args: argparse.Namespace) -> dict[str, Any]:
    import time

    from ...model import ConstrainedModel
    from ...viz.recording import check_frames, play_live, write_recording

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
    if args.live:
        result["live_url"] = play_live(model, trajectory, fps=args.fps)
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
    return ended(result, failure)


def _saved_run(args: argparse.Namespace):
    """(scene, trajectory, None) of ``--from``: the run file read whole, checked against the scene."""
    from ...scene import load_scene
    from ...trajectory import Trajectory
    from ..options import parameters

    scene = load_scene(args.scene, **parameters(args.param))
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
