"""``pinstab sweep``: a scene over the product of grids of its parameters and run options, on Dask, into a CSV or
Parquet table that a re-run resumes; a chart of two of its columns."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ...bench.sweep_grid import MAX_POINTS
from ...errors import PinstabError
from ..exits import EXIT_CODES
from ..options import memory_limit_argument, output_argument, parameters
from .base import Command, register


def arguments(sweep: argparse.ArgumentParser) -> None:
    """The scene, the grids, the fixed values, the table, Dask, the chart."""
    sweep.epilog = EXIT_CODES
    sweep.add_argument(
        "scene", help="bundled scene name (pinch, nfourbar, ...: see docs/guide/scenes.md) or a .toml file"
    )
    sweep.add_argument(
        "--grid",
        action="append",
        required=True,
        metavar="NAME=V1,V2,...",
        help="values of a scene generator parameter (pinch: mu, squeeze, mass; nfourbar: N...) or a run option "
        "(method, integrator, solver, contacts, dt, duration, rtol, atol, drift_limit, record_every, kp, kd...), "
        "read as TOML scalars; repeat: the sweep runs the product of the grids",
    )
    sweep.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a scene parameter or run option every point takes, e.g. duration=0.5",
    )
    output_argument(
        sweep,
        "FILE.csv|FILE.parquet",
        "the table, a row per point appended as it finishes; the points already in it are skipped (a killed sweep "
        "resumes). Parquet needs pyarrow: pip install 'pinstab[sweep]'",
        required=True,
    )
    sweep.add_argument(
        "--scheduler", metavar="ADDRESS", help="run on the Dask scheduler at tcp://host:port (default: local cluster)"
    )
    sweep.add_argument(
        "--chart",
        nargs="+",
        metavar="X Y",
        help="draw column Y against column X of the table (also X,Y) into --chart-file",
    )
    sweep.add_argument("--color", metavar="Z", help="with --chart: the column that colours the markers")
    sweep.add_argument("--chart-file", metavar="FILE.png", help="the chart (default: -o/--out with the suffix .png)")
    sweep.add_argument(
        "--max-points",
        type=int,
        default=MAX_POINTS,
        metavar="N",
        help="the most points the grids may make (default %(default)s: each is checked before any runs, the scene "
        "loaded for each combination of its swept parameters); more are refused before any work",
    )
    memory_limit_argument(sweep)
    sweep.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def sweep(args: argparse.Namespace) -> dict[str, Any]:
    """Check everything (grids, values, table, chart columns and file), run the missing points, draw the chart."""
    from ...bench.sweep import columns, run_sweep
    from ...bench.sweep_chart import check_chart, draw_chart
    from ...bench.sweep_grid import parse_grid
    from ...bench.sweep_table import check_table
    from ...files import check_output

    grids: dict[str, list[Any]] = {}
    for text in args.grid:
        name, values = parse_grid(text)
        if name in grids:
            raise PinstabError(f"--grid {name} given twice; give its values in one --grid {name}=V1,V2,...")
        grids[name] = values
    fixed = parameters(args.param)
    check_table(args.output)
    chart = _chart_columns(args)
    if chart is not None:
        check_chart([*chart, args.color], columns(grids))
        png = args.chart_file or str(Path(args.output).with_suffix(".png"))
        check_output(png, ".png", "chart")
    result = run_sweep(args.scene, grids, args.output, fixed, args.scheduler, not args.quiet, args.max_points)
    if chart is not None:
        title = f"{result['scene']}: {chart[1]} over {chart[0]}"
        result["chart_points"] = draw_chart(args.output, *chart, png, args.color, title)
        result["chart"] = png
    return result


def _chart_columns(args: argparse.Namespace) -> tuple[str, str] | None:
    """``--chart X Y`` or ``--chart X,Y`` as (X, Y); None without ``--chart``. Refuses ``--color`` or
    ``--chart-file`` without it and another number of columns than two."""
    if args.chart is None:
        if args.color or args.chart_file:
            raise PinstabError("--color and --chart-file go with --chart X Y")
        return None
    names = [name for item in args.chart for name in item.split(",") if name]
    if len(names) != 2:
        raise PinstabError(f"--chart takes two columns, X Y or X,Y; got {' '.join(args.chart)!r}")
    return names[0], names[1]


def failures(result: dict[str, Any]) -> str | None:
    """The sweep's failed points in words (exit 6), or None when every point of the table ran."""
    failed = result["failed"] + result["failed_before"]
    if not failed:
        return None
    before = f", {result['failed_before']} of them in an earlier run" if result["failed_before"] else ""
    return f"{failed} of {result['points']} points failed{before}; their rows in {result['out']} name the errors"


register(
    Command(
        "sweep",
        "run a scene over grids of parameters and run options on Dask into a CSV/Parquet table; chart it",
        arguments,
        sweep,
        failures=failures,
        order=7,
    )
)
