"""Parameter sweeps: a scene run over the product of grids of its generator parameters and run options, on
Dask, each finished point appended to a table (:mod:`.sweep_table`) that a re-run resumes.

Every point is checked before any runs (:mod:`.sweep_grid`), their number bounded, the memory budgeted; the points
are submitted a few at a time as others finish, so that the rows come at once and the client holds little; SIGINT
and SIGTERM stop the sweep once the points in flight are written.

A point's row holds its grid values, the run's scalar figures (:data:`FIGURES`, :data:`RUN_FIGURES`) and
``error``: the message of a point whose run failed (its figures empty), so that one failure does not end the
sweep; a point whose run kills the worker processes that take it is such a row too (``KilledWorker``). The
scheduler lost ends the sweep with a named error, the rows so far kept.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Iterator
from concurrent.futures import CancelledError
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from ..contact.modes import Mode
from ..errors import PinstabError
from ..memory import require
from ..scene import load_scene
from ..simulate import simulate
from ..simulate.choice import resolve_contacts
from .cluster import LOCAL_WORKERS, StopAfterFlight, dask_client, progress
from .sweep_grid import MAX_POINTS, METHOD_OPTIONS, CheckedSweep, check_sweep, scene_parameters, sweep_points
from .sweep_table import SweepTable, check_table, existing_rows, point_key

HELD_ROW_OPTIONS = frozenset({"method", "solver", *METHOD_OPTIONS})  # the options of held contacts' rows
FIGURES = (
    "steps",
    "t_end",
    "wall_s",
    "max_position_drift",
    "max_velocity_drift",
    "final_position_drift",
    "energy_start",
    "energy_end",
    "max_energy_balance_error",
    "dynamics_evaluations",
    "solver_fallbacks",
    "branch_changes",
    "min_normal_force",
    "min_cone_margin",
    "max_contact_slip",
    "max_servo_error",
)  # the scalar figures of Trajectory.summary() a row keeps (empty where a run has none)
RUN_FIGURES = ("path", "contact_events", "sliding_s", "held", "stopped")  # from the run's info and contact events
WORKER_BYTES = 256_000_000  # [bytes] a local worker process: the interpreter, pinstab, Pinocchio, Dask (170-185 MB in
# the development venv, 211 MB in a fresh one on the newest releases: tests/test_sweep_control.py measures it)
KEY_BYTES, KEY_VALUE_BYTES = 150, 80  # [bytes] a row's key held for resuming: the tuple and its set slot; a value
# [bytes] a cell converting the journal to Parquet: pyarrow's table takes ~6 (docs/sweeps/pinch.csv), the rest for
# the writer's pages and long error messages
PARQUET_CELL_BYTES = 24
IN_FLIGHT = 2  # points submitted per worker thread: each has its next point queued while one runs


def run_point(
    scene_name: str, point: dict[str, Any], fixed: dict[str, Any], parameters: tuple[str, ...]
) -> dict[str, Any]:
    """Simulate one point (its values over the fixed ones; those named in ``parameters`` go to the scene's
    generator, the others to :func:`~pinstab.simulate.simulate`, but :data:`HELD_ROW_OPTIONS` at a point whose contacts
    are not held) and return its row: the point, the figures, and ``error`` (the failure's type and message; the
    figures then empty).

    Any exception of the run becomes the row's error (a sweep outlives a point that fails, diverges or meets a
    bug); KeyboardInterrupt and SystemExit do not.
    """
    values = {**fixed, **point}
    row: dict[str, Any] = dict(point)
    try:
        options = {name: value for name, value in values.items() if name not in parameters}
        scene = load_scene(scene_name, **{name: value for name, value in values.items() if name in parameters})
        if resolve_contacts(scene, options.get("contacts"))[0] is not None:  # the point's contacts are not rows:
            # the held rows' options (a contacts grid's held points take them) are not its run's; simulate refuses them
            options = {name: value for name, value in options.items() if name not in HELD_ROW_OPTIONS}
        trajectory = simulate(scene, **options)  # contacts not swept or fixed: the scene's choice
        row.update(run_figures(trajectory.summary()), path=trajectory.info.path)
        row["error"] = ""
    except Exception as exc:  # noqa: BLE001 - a failed point is a row (see the docstring)
        return failed_row(point, f"{type(exc).__name__}: {exc}")
    return row


def failed_row(point: dict[str, Any], error: str) -> dict[str, Any]:
    """The row of a point whose run failed: its values, the figures empty, ``error`` (the failure named)."""
    return {**point, **dict.fromkeys((*FIGURES, *RUN_FIGURES)), "error": error}


def run_figures(summary: dict[str, Any]) -> dict[str, Any]:
    """A run's row figures from its summary (:meth:`~pinstab.trajectory.Trajectory.summary`): :data:`FIGURES`
    (None where the run has none) and :data:`RUN_FIGURES` but ``path``: the number of contact events, ``sliding_s``,
    the time [s] during which some contact slides, ``held``: every contact sticking from the start to the end
    (None without event-driven contacts), ``stopped``: why the run ended early (``info.stopped``'s reason), or ''."""
    figures = {name: summary.get(name) for name in FIGURES}
    events = summary.get("contact_events") or []
    stopped = summary.get("stopped") or {}
    figures.update(
        contact_events=len(events),
        sliding_s=_sliding_time(events, summary["t_end"]) if events else None,
        held=all(event["to"] == Mode.STICKING.value for event in events) if events else None,
        stopped=stopped.get("reason", "") if isinstance(stopped, dict) else str(stopped),
    )
    return figures


def _sliding_time(events: list[dict[str, Any]], t_end: float) -> float:
    """The time [s] up to ``t_end`` during which at least one contact is in the sliding mode."""
    modes: dict[str, str] = {}
    total, since = 0.0, None
    for event in sorted(events, key=lambda e: e["t"]):
        modes[event["contact"]] = event["to"]
        sliding = Mode.SLIDING.value in modes.values()
        if sliding and since is None:
            since = event["t"]
        elif not sliding and since is not None:
            total, since = total + event["t"] - since, None
    return total + (t_end - since if since is not None else 0.0)


def columns(grids: Iterable[str]) -> list[str]:
    """A sweep table's columns: the grid names, :data:`FIGURES`, :data:`RUN_FIGURES`, ``error``."""
    return [*grids, *FIGURES, *RUN_FIGURES, "error"]


def run_sweep(
    scene_name: str,
    grids: dict[str, list[Any]],
    out: str | Path,
    fixed: dict[str, Any] | None = None,
    scheduler: str | None = None,
    show_progress: bool = False,
    max_points: int = MAX_POINTS,
) -> dict[str, Any]:
    """Run ``scene_name`` at every point of the grids on Dask, appending each finished point's row to ``out``
    (``.csv``, or ``.parquet`` with pyarrow); the points already in ``out`` are skipped (a killed sweep resumes).

    Args:
        scene_name: a bundled scene's name or a scene file.
        grids: name -> values: generator parameters of the scene (``mu``, ``squeeze``; ``N``) or run options
            (``method``, ``dt`` [s], ``duration`` [s], ``kp`` [1/s^2]...: :data:`~.sweep_grid.RUN_OPTIONS`).
        out: the table. fixed: name -> the value every point takes. scheduler: a Dask scheduler's address
            (default: an embedded LocalCluster). show_progress: a progress bar on stderr. max_points: the most
            points the grids may make (:data:`~.sweep_grid.MAX_POINTS`).

    Returns:
        ``points``, ``skipped`` (already in ``out``), ``ran``, ``failed`` (rows with an error, this run),
        ``failed_before`` (skipped points whose row holds an error), ``out``.

    Raises:
        PinstabError: refused before any work (:func:`~.sweep_grid.check_sweep`: a name, a value, a point, their
            number; the output: :class:`SweepTable`), MemoryBudgetError (:func:`sweep_memory`), a scheduler
            that cannot be reached, or one lost during the sweep (the rows so far kept).
        Stopped: SIGINT or SIGTERM (a KeyboardInterrupt): the points in flight were written, the table closed
            (a Parquet table converted) and kept; during the checks before any work, nothing written.
    """
    fixed = dict(fixed or {})
    checked = check_sweep(scene_name, grids, fixed, max_points, show_progress)
    scene = checked.scene
    path = check_table(out)
    require(
        sweep_memory(checked, existing_rows(path), list(grids), path.suffix == ".parquet", scheduler is None),
        f"a sweep of {checked.points:,} points of scene {scene.name}",
        "sweep fewer points at once (a table resumes: sweep some values, then the others into it)",
    )
    table = SweepTable(path, columns(grids), len(grids))
    skipped = failed_before = 0
    for point in sweep_points(grids) if table.done else ():  # a new table: no pass over the points
        key = point_key(point.values())
        skipped += key in table.done
        failed_before += key in table.failed
    pending = (point for point in sweep_points(grids) if point_key(point.values()) not in table.done)
    ran = checked.points - skipped
    source, names = str(scene.source or scene_name), tuple(scene_parameters(scene))
    running = dask_client(scheduler, "sweep", "pip install 'pinstab[sweep]'") if ran else nullcontext()
    written = failed = 0
    with StopAfterFlight() as stop, running as client, table:  # the client first: no table for a scheduler away
        rows = _rows(client, (source, fixed, names), pending, stop) if ran else iter(())
        try:
            for row in progress(rows, show_progress, "sweep", total=checked.points, initial=skipped):
                failed += bool(row["error"])
                table.append(row)
                written += 1
        except _ClusterLost as lost:
            where = scheduler or "of the local cluster"
            raise PinstabError(
                f"sweep: the Dask scheduler {where} was lost ({lost}); {written} new rows in {out}, resumed by a re-run"
            ) from None
    stop.deliver(f"the sweep stopped after its points in flight; {written} new rows in {out}, resumed by a re-run")
    return {
        "scene": scene.name,
        "points": checked.points,
        "skipped": skipped,
        "ran": ran,
        "failed": failed,
        "failed_before": failed_before,
        "out": str(out),
    }


def sweep_memory(checked: CheckedSweep, rows: int, grids: list[str], parquet: bool, local: bool) -> dict[str, int]:
    """The estimated memory of a sweep [bytes] by item: on the local cluster (``local``), its worker processes each
    running the point whose run takes the most; the keys of the table's ``rows`` (those already in it, read to
    resume it), and with ``parquet`` the conversion of every row. The points are made one at a time as they are
    submitted: none is held ahead."""
    items = {}
    if local:
        largest = ", ".join(f"{name} {size:,} B" for name, size in checked.run_memory.items())
        items[f"{LOCAL_WORKERS} worker processes each running the largest point ({largest})"] = LOCAL_WORKERS * (
            WORKER_BYTES + sum(checked.run_memory.values())
        )
    items[f"the keys of the table's {rows:,} rows"] = rows * (KEY_BYTES + KEY_VALUE_BYTES * len(grids))
    if parquet:
        total = rows + checked.points
        items[f"the Parquet conversion of {total:,} rows"] = total * len(columns(grids)) * PARQUET_CELL_BYTES
    return items


def _rows(client: Any, sweep: tuple[str, dict[str, Any], tuple[str, ...]], pending: Iterator[dict], stop):
    """The rows of the ``pending`` points as they finish (:func:`run_point` of each with the ``sweep``'s scene,
    fixed values and scene parameters), :data:`IN_FLIGHT` per worker thread submitted at a time (each finished
    one replaced by the next), none submitted once ``stop`` (:class:`~.cluster.StopAfterFlight`) has a signal.

    A point whose run killed the workers that took it (Dask gave it up: ``KilledWorker``) is a failed row naming
    it (:func:`_killed_worker`); the scheduler lost (the whole cluster) raises :class:`_ClusterLost`."""
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    source, fixed, names = sweep
    points: dict[Any, dict[str, Any]] = {}  # future's key -> its point

    def submit(point: dict[str, Any]) -> Any:
        future = client.submit(run_point, source, point, fixed, names, pure=False)
        points[future.key] = point
        return future

    try:
        window = IN_FLIGHT * max(1, sum(client.nthreads().values()))
        flight = as_completed([submit(point) for point in itertools.islice(pending, window)])
        for future in flight:
            if stop.signum is None:
                for point in itertools.islice(pending, 1):
                    flight.add(submit(point))
            point = points.pop(future.key)
            try:
                row = future.result()
            except KilledWorker as exc:
                row = failed_row(point, _killed_worker(exc))
            yield row
    except (CancelledError, OSError) as exc:  # futures cancelled, a connection closed: the scheduler is gone
        raise _ClusterLost(" ".join(f"{type(exc).__name__}: {exc}".split())) from None  # Dask's lines as one


def _killed_worker(exc: Exception) -> str:
    """The error of a point Dask gave up (``distributed.scheduler.KilledWorker``): the workers that ran it died."""
    tries = getattr(exc, "allowed_failures", 0) + 1
    return (
        f"KilledWorker: every Dask worker that ran this point died ({tries} of them: a crash in compiled code, an exit "
        "of the process, or memory beyond the worker's limit) and Dask gave the point up; its run never finished"
    )


class _ClusterLost(Exception):
    """The Dask scheduler of a sweep was lost while points were in flight (the message: Dask's error)."""
