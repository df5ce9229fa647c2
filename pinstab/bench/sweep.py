"""Parameter sweeps: a scene run over the product of grids of its generator parameters and run options, on
Dask, each finished point appended to a table (:mod:`.sweep_table`) that a re-run resumes.

A point's row holds its grid values, the run's scalar figures (:data:`FIGURES`, :data:`RUN_FIGURES`) and
``error``: the message of a point whose run failed (its figures empty), so that one failure does not end the
sweep.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from ..contact.modes import Mode
from ..errors import PinstabError, choices
from ..generators import GENERATOR_PARAMETERS
from ..integration import INTEGRATORS
from ..registry import option_fields
from ..scene import Scene, load_scene
from ..simulate import HELD_ONLY, default_contacts, simulate
from ..solvers import SOLVERS
from ..stabilizers import STABILIZERS
from ..tables import toml_scalar
from .cluster import dask_client, progress
from .sweep_table import SweepTable, point_key

CONTACT_TREATMENTS = ("event", "stepping", "held")  # held: simulate(contacts=None)
NAMED_CHOICES = {"method": STABILIZERS, "integrator": INTEGRATORS, "solver": SOLVERS, "contacts": CONTACT_TREATMENTS}
SIMULATE_OPTIONS: dict[str, type] = {
    "method": str,
    "integrator": str,
    "solver": str,
    "contacts": str,
    "dt": float,
    "duration": float,
    "rtol": float,
    "atol": float,
    "drift_limit": float,
    "record_every": int,
}  # the keywords of simulate() a sweep sets
METHOD_OPTIONS = {field.name: field.kind for entry in STABILIZERS.entries() for field in option_fields(entry.options)}
RUN_OPTIONS = {**SIMULATE_OPTIONS, **METHOD_OPTIONS}  # kp, kd [1/s^2], [1/s]...: the methods' options
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


def parse_grid(text: str) -> tuple[str, list[Any]]:
    """``NAME=V1,V2,...`` -> (NAME, [V1, V2, ...]), the values read as TOML scalars (``0.5`` a float, ``20`` an
    int, ``rk4`` a string).

    Raises:
        PinstabError: no ``=``, no name, an empty value or a value given twice.
    """
    name, sep, listed = text.partition("=")
    name = name.strip()
    values = [toml_scalar(item.strip()) for item in listed.split(",")]
    if not sep or not name or any(value == "" for value in values):
        raise PinstabError(f"--grid expects NAME=V1,V2,..., got {text!r}")
    keys = [point_key([value]) for value in values]
    repeated = sorted({key for key in keys if keys.count(key) > 1})
    if repeated:
        raise PinstabError(f"--grid {name}: value {repeated[0][0]} given twice; give each value once")
    return name, values


def scene_parameters(scene: Scene) -> list[str]:
    """The generator parameters of ``scene`` (none for a scene without a ``[generator]``)."""
    return list(GENERATOR_PARAMETERS.get(scene.generator or "", {}))


def sweep_names(scene: Scene) -> list[str]:
    """The names a sweep of ``scene`` takes: its generator's parameters, then :data:`RUN_OPTIONS`."""
    parameters = scene_parameters(scene)
    return parameters + [name for name in RUN_OPTIONS if name not in parameters]


def check_sweep(scene_name: str, grids: dict[str, list[Any]], fixed: dict[str, Any]) -> Scene:
    """Refuse a sweep before any work; returns the scene (without the fixed values).

    Refused: no grid, a name that is neither a generator parameter of the scene nor a run option (the error
    lists the valid ones), a name both swept and fixed, a run option's value of the wrong type or not among its
    choices, a scene parameter's value the generator refuses (each value loaded once, over the fixed ones), the
    held contacts' options (``method``, ``kp``...) on a scene whose contacts are event-driven.

    Args:
        scene_name: a bundled scene's name or a scene file. grids: name -> values. fixed: name -> the value
            every point takes.

    Raises:
        PinstabError (SceneError for the scene's own refusals).
    """
    if not grids:
        raise PinstabError("sweep: give at least one --grid NAME=V1,V2,...")
    scene = load_scene(scene_name)
    valid = sweep_names(scene)
    for name in [*grids, *fixed]:
        if name not in valid:
            raise PinstabError(f"sweep {scene.name}: unknown name {name!r}; valid names: {', '.join(valid)}")
    both = sorted(set(grids) & set(fixed))
    if both:
        raise PinstabError(f"sweep: {both[0]} is both swept (--grid) and fixed (--param); give it once")
    names = scene_parameters(scene)
    parameters = {name: value for name, value in fixed.items() if name in names}
    loaded = load_scene(scene_name, **parameters) if parameters else scene
    for name, values in [*grids.items(), *((name, [value]) for name, value in fixed.items())]:
        for value in values:
            if name not in names:
                _check_option(name, value)
            elif name in grids:
                load_scene(scene_name, **parameters, **{name: value})
    contacts = fixed.get("contacts", default_contacts(loaded) or "held")
    held_only = [name for name in [*grids, *fixed] if name in HELD_ONLY or name in METHOD_OPTIONS]
    if contacts == "event" and "contacts" not in grids and held_only:
        raise PinstabError(
            f"sweep {scene.name}: {', '.join(held_only)} set, but the contacts are event-driven (error-controlled "
            "dop853, no stabilization method or KKT backend); fix or sweep contacts=held to use them"
        )
    return scene


def _check_option(name: str, value: Any) -> None:
    """Refuse a run option's value of the wrong type [number, int, name] or outside its choices."""
    kind = RUN_OPTIONS[name]
    if name in NAMED_CHOICES:
        if value not in NAMED_CHOICES[name]:
            raise PinstabError(f"sweep: {name} {value!r} unknown; valid: {choices(NAMED_CHOICES[name])}")
        return
    if kind is float:
        good = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    else:
        good = isinstance(value, kind) and not (kind is int and isinstance(value, bool))
    if not good:
        raise PinstabError(f"sweep: {name} takes a {kind.__name__}, got {value!r}")


def sweep_points(grids: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """Every point of the product of the grids, the last grid varying fastest."""
    return [dict(zip(grids, values, strict=True)) for values in itertools.product(*grids.values())]


def run_point(
    scene_name: str, point: dict[str, Any], fixed: dict[str, Any], parameters: tuple[str, ...]
) -> dict[str, Any]:
    """Simulate one point (its values over the fixed ones; those named in ``parameters`` go to the scene's
    generator, the others to :func:`~pinstab.simulate.simulate`) and return its row: the point, the figures,
    and ``error`` (the failure's type and message; the figures then empty).

    Any exception of the run becomes the row's error (a sweep outlives a point that fails, diverges or meets a
    bug); KeyboardInterrupt and SystemExit do not.
    """
    values = {**fixed, **point}
    row: dict[str, Any] = dict(point)
    try:
        options = {name: value for name, value in values.items() if name not in parameters}
        scene = load_scene(scene_name, **{name: value for name, value in values.items() if name in parameters})
        contacts = options.pop("contacts", None) or default_contacts(scene) or "held"
        trajectory = simulate(scene, contacts=None if contacts == "held" else contacts, **options)
        row.update(run_figures(trajectory.summary()), path=trajectory.info.path)
        row["error"] = ""
    except Exception as exc:  # noqa: BLE001 - a failed point is a row (see the docstring)
        row.update(dict.fromkeys((*FIGURES, *RUN_FIGURES)))
        row["error"] = f"{type(exc).__name__}: {exc}"
    return row


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


def columns(grids: dict[str, list[Any]]) -> list[str]:
    """A sweep table's columns: the grid names, :data:`FIGURES`, :data:`RUN_FIGURES`, ``error``."""
    return [*grids, *FIGURES, *RUN_FIGURES, "error"]


def run_sweep(
    scene_name: str,
    grids: dict[str, list[Any]],
    out: str | Path,
    fixed: dict[str, Any] | None = None,
    scheduler: str | None = None,
    show_progress: bool = False,
) -> dict[str, Any]:
    """Run ``scene_name`` at every point of the grids on Dask, appending each finished point's row to ``out``
    (``.csv``, or ``.parquet`` with pyarrow); the points already in ``out`` are skipped (a killed sweep resumes).

    Args:
        scene_name: a bundled scene's name or a scene file.
        grids: name -> values: generator parameters of the scene (``mu``, ``squeeze``; ``N``) or run options
            (:data:`RUN_OPTIONS`: ``method``, ``dt`` [s], ``duration`` [s], ``kp`` [1/s^2]...).
        out: the table. fixed: name -> the value every point takes. scheduler: a Dask scheduler's address
            (default: an embedded LocalCluster). show_progress: a progress bar on stderr.

    Returns:
        ``points``, ``skipped`` (already in ``out``), ``ran``, ``failed`` (rows with an error, this run),
        ``failed_before`` (skipped points whose row holds an error), ``out``.

    Raises:
        PinstabError: refused before any work (:func:`check_sweep`, the output: :class:`SweepTable`), or a
            scheduler that cannot be reached.
    """
    fixed = dict(fixed or {})
    scene = check_sweep(scene_name, grids, fixed)
    source, names = str(scene.source or scene_name), tuple(scene_parameters(scene))
    points = sweep_points(grids)
    failed = 0
    table = SweepTable(out, columns(grids), len(grids))
    keys = [point_key(point.values()) for point in points]
    pending = [point for point, key in zip(points, keys, strict=True) if key not in table.done]
    running = dask_client(scheduler, "sweep", "pip install 'pinstab[sweep]'") if pending else nullcontext()
    with running as client, table:  # the client first: no table is started for a scheduler out of reach
        futures = [client.submit(run_point, source, point, fixed, names, pure=False) for point in pending]
        skipped = len(points) - len(pending)
        for future in progress(_finished(futures), show_progress, "sweep", total=len(points), initial=skipped):
            row = future.result()
            failed += bool(row["error"])
            table.append(row)
    return {
        "scene": scene.name,
        "points": len(points),
        "skipped": len(points) - len(pending),
        "ran": len(pending),
        "failed": failed,
        "failed_before": sum(key in table.failed for key in keys),
        "out": str(out),
    }


def _finished(futures: list[Any]) -> Iterator[Any]:
    """The futures as they finish (none: nothing)."""
    if not futures:
        return iter(())
    from distributed import as_completed

    return as_completed(futures)
