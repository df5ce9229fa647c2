"""``pinstab stability``: map observed against predicted stability over a (dt, gain) grid."""

from __future__ import annotations

import argparse
from typing import Any

from ...analysis.stability_map import map_methods
from ...files import check_output
from ...integration import INTEGRATORS
from ...solvers import SOLVERS
from ..options import output_argument, scene_arguments, scene_options
from .base import Command, register


def arguments(stability: argparse.ArgumentParser) -> None:
    """The scene, the method and integrator, the grid of steps and gains, ``-o``."""
    scene_arguments(stability)
    stability.add_argument(
        "--method", default="baumgarte", choices=map_methods(), help="a method with gains kp, kd (default: baumgarte)"
    )
    stability.add_argument(
        "--integrator", default="semi-implicit-euler", choices=INTEGRATORS, help="(default: semi-implicit-euler)"
    )
    stability.add_argument(
        "--dt-range",
        nargs=2,
        type=float,
        default=[1e-4, 3e-2],
        metavar=("A", "B"),
        help="steps [s] (default: 1e-4 3e-2)",
    )
    stability.add_argument(
        "--gain-range",
        nargs=2,
        type=float,
        default=[1e2, 1e9],
        metavar=("C", "D"),
        help="Kp [1/s^2], Kd = 2 sqrt(Kp) (default: 1e2 1e9)",
    )
    stability.add_argument("--grid", type=int, default=40, help="cells per axis (default: 40)")
    stability.add_argument("--steps", type=int, default=200, help="steps per run (default: 200)")
    stability.add_argument("--perturbation", type=float, default=0.01, help="initial violation [rad] (default: 0.01)")
    stability.add_argument(
        "--solver", default="dense", choices=SOLVERS, help="KKT backend of the runs (default: dense)"
    )
    output_argument(stability, "MAP.png", "write the map as a PNG")


def stability(args: argparse.Namespace) -> dict[str, Any]:
    from ...analysis.stability_map import plot_stability_map, stability_map
    from ...scene import load_scene

    if args.output:
        check_output(args.output, ".png", "chart")
    scene = load_scene(args.scene, **scene_options(args))
    result = stability_map(
        scene,
        method=args.method,
        integrator=args.integrator,
        dt_range=tuple(args.dt_range),
        gain_range=tuple(args.gain_range),
        grid=args.grid,
        steps=args.steps,
        perturbation=args.perturbation,
        solver=args.solver,
        progress=not args.quiet,
    )
    if args.output:
        plot_stability_map(result, args.output)
    payload = result.to_json()
    if not args.json:
        counts = {name: sum(c.observed == name for c in result.cells) for name in ("converged", "bounded", "diverged")}
        payload = {k: v for k, v in payload.items() if k != "cells"} | counts
    if args.output:
        payload["map"] = args.output
    return payload


register(
    Command(
        "stability",
        "map observed vs predicted stability over a (dt, gain) grid",
        arguments,
        stability,
        order=7,
    )
)
