"""``pinstab bench``: the work-precision sweep with peers, overhead and scaling; charts and tables."""

from __future__ import annotations

import argparse
from typing import Any

from ...bench.workprecision import MUJOCO_DTS, PEER_DTS, RTOLS
from ...errors import PinstabError
from ...integration import INTEGRATORS
from ...simulate import MIN_RTOL
from ...stabilizers import STABILIZERS
from ..options import output_argument, parameters
from .base import Command, register


def arguments(bench: argparse.ArgumentParser) -> None:
    """The scene, the methods, integrators, steps and tolerances of the sweep, the output folder, Dask."""
    bench.add_argument("scene", help="bundled scene name or a .toml file")
    bench.add_argument("--param", action="append", default=[], metavar="NAME=VALUE", help="scene generator parameter")
    bench.add_argument(
        "--methods", nargs="+", default=["baumgarte", "mukharlyamov", "projection", "pinocchio"], choices=STABILIZERS
    )
    bench.add_argument(
        "--integrators", nargs="+", default=["semi-implicit-euler", "rk4", "dop853"], choices=INTEGRATORS
    )
    bench.add_argument("--dts", nargs="+", type=float, default=[4e-3, 2e-3, 1e-3], help="pinstab's steps [s]")
    for flag, steps, whose in (
        ("--peer-dts", PEER_DTS, "the hand-written Pinocchio loop's steps [s]"),
        ("--mujoco-dts", MUJOCO_DTS, "MuJoCo's steps [s], each with solref 2 dt"),
        (
            "--rtols",
            RTOLS,
            "tolerances of the error-controlled runs, pinstab's dop853 --rtol and SciPy's DOP853, Radau and BDF",
        ),
    ):
        listed = ", ".join(f"{dt:g}" for dt in steps)
        bench.add_argument(flag, nargs="+", type=float, default=list(steps), help=f"{whose} (default: {listed})")
    bench.add_argument("--duration", type=float, default=2.0, help="simulated time [s] (default: 2)")
    output_argument(bench, "DIR", "folder for results.json/.csv and charts", required=True)
    bench.add_argument(
        "--scheduler", metavar="ADDRESS", help="join a Dask scheduler (tcp://host:port); default: local cluster"
    )
    bench.add_argument("--serial", action="store_true", help="run in this process instead of on Dask")
    bench.add_argument(
        "--tolerance", type=float, default=1e-6, help="trajectory error for the cost comparison [rad, m]"
    )
    bench.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def bench(args: argparse.Namespace) -> dict[str, Any]:
    from pathlib import Path

    from ...bench.overhead import measure_overhead
    from ...bench.scaling import scaling
    from ...bench.workprecision import (
        cheapest_table,
        check_tolerance,
        default_configs,
        make_output_folder,
        sweep,
        write_outputs,
    )
    from ...scene import load_scene

    given = parameters(args.param)
    scene = load_scene(args.scene, **given)  # validates the scene before any work
    for flag, steps in (("--dts", args.dts), ("--peer-dts", args.peer_dts), ("--mujoco-dts", args.mujoco_dts)):
        for dt in steps:
            if not dt > 0:
                raise PinstabError(f"{flag}: steps must be positive, got {dt}")
    for rtol in args.rtols:
        if not MIN_RTOL <= rtol < 1:
            raise PinstabError(f"--rtols: tolerances must be in [{MIN_RTOL:g}, 1), got {rtol}")
    check_tolerance(args.tolerance)
    out_dir = Path(args.output)
    make_output_folder(out_dir)
    configs = default_configs(
        args.methods,
        args.integrators,
        sorted(args.dts),
        peer_dts=tuple(sorted(args.peer_dts)),
        mujoco_dts=tuple(sorted(args.mujoco_dts)),
        rtols=tuple(sorted(args.rtols)),
        constrained=bool(scene.constraints),
    )
    reference, results = sweep(
        str(scene.source or args.scene), given, configs, args.duration, args.scheduler, args.serial, not args.quiet
    )
    extra: dict[str, Any] = {"duration": args.duration, "tolerance": args.tolerance}
    extra["cheapest"] = cheapest_table(results, args.tolerance)
    extra["overhead"] = measure_overhead(scene, scene.step or 1e-3)  # at the scene's step: a stiff one needs its own
    extra["overhead_ratio"] = extra["overhead"]["overhead_ratio"]
    if scene.parameters and "N" in scene.parameters and scene.name == "nfourbar":
        extra["scaling"] = scaling()
        extra["scaling_exponent"] = extra["scaling"]["scaling_exponent"]
    summary = write_outputs(out_dir, scene.name, reference, results, extra)
    if not args.json:
        return {k: v for k, v in summary.items() if k not in ("results", "overhead", "scaling")} | {
            "output": str(out_dir)
        }
    return summary


register(
    Command(
        "bench",
        "work-precision sweep with peers, overhead and scaling; charts and tables",
        arguments,
        bench,
        order=6,
    )
)
