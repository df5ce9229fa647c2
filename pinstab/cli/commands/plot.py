"""``pinstab plot``: chart a saved run."""

from __future__ import annotations

import argparse
from typing import Any

from ...files import check_output
from ..options import output_argument
from .base import Command, register


def arguments(plot: argparse.ArgumentParser) -> None:
    """The saved run, ``-o``, ``--json``."""
    plot.add_argument("run_file", metavar="RUN.npz|RUN.h5", help="a saved (--save) or streamed (--stream) run")
    output_argument(plot, "OUT.png", "the chart to write", required=True)
    plot.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def plot(args: argparse.Namespace) -> dict[str, Any]:
    from ...trajectory import Trajectory
    from ...viz.plots import plot_trajectory

    check_output(args.output, ".png", "chart")
    trajectory = Trajectory.load(args.run_file)
    plot_trajectory(trajectory, args.output)
    info = trajectory.info
    return {
        "run": args.run_file,
        "plot": args.output,
        "steps": trajectory.steps,
        "t_end": float(trajectory.t[-1]),
        "stopped": info.stopped,
        "cut_short": info.cut_short,
        "contact_events": info.contact_events,
    }


register(
    Command("plot", "chart a saved run (drift, energy budget and error, constraint forces)", arguments, plot, order=5)
)
