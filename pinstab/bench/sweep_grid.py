"""A sweep's grids: what they may name, their points, and every point checked before any runs, by the checks a
run makes before its first step (the same functions, the same messages: the values, the system built, the start
inside the joint limits and assembled), the number of points bounded; the check shows its progress and stops on
SIGINT or SIGTERM."""

from __future__ import annotations

import inspect
import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from ..assembly import assemble
from ..errors import PinstabError, choices
from ..generators import GENERATOR_PARAMETERS
from ..integration import INTEGRATORS, TimeGrid
from ..model import ConstrainedModel
from ..registry import option_fields
from ..scene import Scene, load_scene
from ..simulate import DEFAULT_DT, HELD_ONLY, default_contacts, default_integrator, error_control, simulate
from ..simulate.contacts import contact_system
from ..simulate.held import held_system
from ..simulate.limits import held_limits
from ..simulate.loop import check_drift_limit, run_memory, start_state
from ..solvers import SOLVERS
from ..stabilizers import STABILIZERS
from ..tables import toml_scalar
from .cluster import Stopped, progress
from .sweep_table import point_key

CONTACT_TREATMENTS = ("event", "stepping", "held")  # held: the constraint rows of simulate(contacts="held")
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
# simulate()'s defaults: duration [s], record_every, drift_limit [m or rad], method...
DEFAULTS = {name: parameter.default for name, parameter in inspect.signature(simulate).parameters.items()}
# Each point is checked before any runs: the scene loaded for each combination of its swept parameters (1 to 9 ms a
# load for the bundled scenes), its start checked (0.3 to 1.2 ms) and its systems built (0.1 to 0.3 ms each): about
# 15 s for 10,000 of pinch's (timeit: the least of 5 x 50), a progress bar from
# CHECK_BAR_DELAY. Each point is then a whole run (from 10 ms to seconds: 10,000 points keep the two local workers
# busy from a minute to hours). A grid beyond it is more often long value lists multiplied by mistake than a plan:
# --max-points asks for it.
MAX_POINTS = 10_000
CHECK_BAR_DELAY = 2.0  # [s] the checks' progress bar shows once they last this long (most take well under it)


@dataclass(frozen=True)
class CheckedSweep:
    """A sweep found valid before any work.

    Attributes:
        scene: the scene (without the fixed values). points: how many points the grids make. run_memory: the
            estimated memory [bytes] by item of the point whose run takes the most (``simulate.loop.run_memory``).
    """

    scene: Scene
    points: int
    run_memory: dict[str, int]


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


def sweep_points(grids: dict[str, list[Any]]) -> Iterator[dict[str, Any]]:
    """Every point of the product of the grids, the last grid varying fastest, one at a time (none is built
    ahead)."""
    return (dict(zip(grids, values, strict=True)) for values in itertools.product(*grids.values()))


def point_count(grids: dict[str, list[Any]]) -> int:
    """How many points the product of the grids has."""
    return math.prod(len(values) for values in grids.values())


def check_sweep(
    scene_name: str,
    grids: dict[str, list[Any]],
    fixed: dict[str, Any],
    max_points: int = MAX_POINTS,
    show_progress: bool = False,
) -> CheckedSweep:
    """Refuse a sweep before any work: the names and values, then (:func:`check_points`) every point.

    Refused: no grid, a name that is neither a generator parameter of the scene nor a run option (the error
    lists the valid ones), a name both swept and fixed, a run option's value of the wrong type or not among its
    choices, the held contacts' options (``method``, ``kp``...) on a scene whose contacts are event-driven, more
    points than ``max_points``, a point the scene or a run refuses before its first step (:data:`RUN_CHECKS`: its
    values, the system it builds, its start).

    Args:
        scene_name: a bundled scene's name or a scene file. grids: name -> values. fixed: name -> the value
            every point takes. max_points: the most points the sweep may have (:data:`MAX_POINTS`).
            show_progress: the checks' progress bar on stderr (:func:`check_points`).

    Raises:
        PinstabError (SceneError for the scene's own refusals; the point named in the message).
        Stopped: SIGINT or SIGTERM during the checks (:func:`check_points`).
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
    for name, values in [*grids.items(), *((name, [value]) for name, value in fixed.items())]:
        if name not in names:
            for value in values:
                _check_option(name, value)
    held_only = [name for name in [*grids, *fixed] if name in HELD_ONLY or name in METHOD_OPTIONS]
    if "contacts" not in grids and held_only and _contacts(fixed, scene_name, names) == "event":
        raise PinstabError(
            f"sweep {scene.name}: {', '.join(held_only)} set, but the contacts are event-driven (error-controlled "
            "dop853, no stabilization method or KKT backend); fix or sweep contacts=held to use them"
        )
    if isinstance(max_points, bool) or not isinstance(max_points, int) or max_points < 1:
        raise PinstabError(f"sweep: max_points (--max-points) must be a whole number >= 1, got {max_points!r}")
    count = point_count(grids)
    if count > max_points:
        sizes = " x ".join(f"{len(values)} {name}" for name, values in grids.items())
        raise PinstabError(
            f"sweep: {count:,} points ({sizes}) exceed the limit of {max_points:,}; sweep fewer values, or give "
            f"--max-points {count} (max_points) to run them all"
        )
    return CheckedSweep(scene, count, check_points(scene_name, grids, fixed, tuple(names), show_progress))


def _contacts(fixed: dict[str, Any], scene_name: str, names: list[str]) -> str:
    """The contact treatment of the fixed values: theirs, else the default of the scene they make."""
    if "contacts" in fixed:
        return fixed["contacts"]
    scene = load_scene(scene_name, **{name: value for name, value in fixed.items() if name in names})
    return default_contacts(scene)


def _check_option(name: str, value: Any) -> None:
    """Refuse a run option's value of the wrong type [number, int, name] or outside its choices."""
    kind = RUN_OPTIONS[name]
    if name in NAMED_CHOICES:
        if value not in NAMED_CHOICES[name]:
            raise PinstabError(f"sweep: {name} {value!r} unknown; valid: {choices(NAMED_CHOICES[name])}")
        return
    if kind is float:  # its range (finite or not...) is the run's to check (RUN_CHECKS)
        good = isinstance(value, int | float) and not isinstance(value, bool)
    else:
        good = isinstance(value, kind) and not (kind is int and isinstance(value, bool))
    if not good:
        raise PinstabError(f"sweep: {name} takes a {kind.__name__}, got {value!r}")


def check_points(
    scene_name: str,
    grids: dict[str, list[Any]],
    fixed: dict[str, Any],
    parameters: tuple[str, ...],
    show_progress: bool = False,
) -> dict[str, int]:
    """Refuse before any work a point whose scene or run would be refused: each combination of the swept scene
    parameters loaded (over the fixed ones), and for each such scene each check of :data:`RUN_CHECKS` made on every
    combination of the values it reads (and ``contacts``, which decides whether it applies). A point passes the
    checks iff its values pass each: 10^6 points of 1000 kp x 1000 drift_limit cost 3002 checks (a scene load,
    1000 drift limits, 1000 kp options and 1000 systems built with them, a start).

    Args:
        show_progress: a progress bar on stderr (the checks made of how many), shown once they have lasted
            :data:`CHECK_BAR_DELAY`.

    Returns:
        The estimated memory [bytes] by item of the run that takes the most (``simulate.loop.run_memory``).

    Raises:
        PinstabError: the first refusal (its class: SceneError from the scene...), its message the run's, prefixed
            by the values that make it (``sweep point dt=0: dt must be a positive number, got 0``).
        Stopped: SIGINT or SIGTERM (a KeyboardInterrupt) during the checks: nothing was written.
    """
    scene_grids = {name: values for name, values in grids.items() if name in parameters}
    checks = sum(point_count(_read(grids, names)) for names, _ in RUN_CHECKS)
    total = point_count(scene_grids) * (1 + checks)  # a scene load and its checks
    made = progress(
        _checks(scene_name, grids, fixed, parameters), show_progress, "checking the points", total, 0, "check",
        CHECK_BAR_DELAY,
    )  # fmt: skip
    largest: dict[str, int] = {}
    done = 0
    try:
        for memory in made:
            done += 1
            if memory is not None and sum(memory.values()) > sum(largest.values()):
                largest = memory
    except KeyboardInterrupt:
        count = f"{done:,} of {total:,} checks made"
        raise Stopped(f"the sweep was still checking its points ({count}): nothing was written") from None
    return largest


def _checks(
    scene_name: str, grids: dict[str, list[Any]], fixed: dict[str, Any], parameters: tuple[str, ...]
) -> Iterator[dict[str, int] | None]:
    """The checks of :func:`check_points` made one at a time: each combination of the swept scene parameters loaded
    (yields None), then each check of :data:`RUN_CHECKS` on each combination of the values it reads (yields what it
    returns: the run's memory by item [bytes], or None)."""
    scene_grids = {name: values for name, values in grids.items() if name in parameters}
    fixed_parameters = {name: value for name, value in fixed.items() if name in parameters}
    fixed_options = {name: value for name, value in fixed.items() if name not in parameters}
    for scene_point in sweep_points(scene_grids):
        scene = _at_point(scene_point, load_scene, scene_name, **fixed_parameters, **scene_point)
        yield None
        for names, check in RUN_CHECKS:
            for point in sweep_points(_read(grids, names)):
                options = {**fixed_options, **point}
                contacts = options.get("contacts") or default_contacts(scene)
                yield _at_point({**scene_point, **point}, check, scene, contacts, options)


def _read(grids: dict[str, list[Any]], names: tuple[str, ...]) -> dict[str, list[Any]]:
    """The grids a check of :data:`RUN_CHECKS` reads: those of ``names``, and ``contacts``."""
    return {name: values for name, values in grids.items() if name in names or name == "contacts"}


def _at_point(point: dict[str, Any], check: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    """``check(*args, **kwargs)``, its PinstabError's message prefixed by ``point``'s values (the same class)."""
    try:
        return check(*args, **kwargs)
    except PinstabError as exc:
        if point:
            exc.args = (f"sweep point {', '.join(f'{name}={value}' for name, value in point.items())}: {exc}",)
        raise


# The checks simulate() makes before its first step, each on the run options it reads, with the scene and the
# contact treatment (event, stepping, held); each raises the run's PinstabError. Options not given take simulate()'s
# defaults (DEFAULTS), dt the scene's [run] dt, else DEFAULT_DT.
def _time_grid(scene: Scene, contacts: str, options: dict[str, Any]) -> dict[str, int]:
    """``dt`` [s], ``duration`` [s], ``record_every``: ``TimeGrid.of``; returns the run's memory by item [bytes]."""
    every = options.get("record_every", DEFAULTS["record_every"])
    dt = options.get("dt", DEFAULT_DT if scene.step is None else scene.step)
    grid = TimeGrid.of(dt, options.get("duration", DEFAULTS["duration"]), every)
    return run_memory(scene, grid, every, None)


def _tolerances(scene: Scene, contacts: str, options: dict[str, Any]) -> None:
    """``rtol``, ``atol`` (with the ``integrator`` they control: dop853 with event-driven contacts; none with
    time-stepping contacts): ``error_control``."""
    rtol, atol = options.get("rtol"), options.get("atol")
    if contacts != "stepping" and (rtol is not None or atol is not None):
        integrator = "dop853" if contacts == "event" else default_integrator(options.get("integrator"), rtol, atol)
        error_control(rtol, atol, integrator)


def _drift_limit(scene: Scene, contacts: str, options: dict[str, Any]) -> None:
    """``drift_limit`` [m or rad] of held contacts: ``check_drift_limit``."""
    if contacts == "held":
        check_drift_limit(options.get("drift_limit", DEFAULTS["drift_limit"]))


def _method_options(scene: Scene, contacts: str, options: dict[str, Any]) -> None:
    """The ``method``'s options of held contacts (``kp`` [1/s^2], ``kd`` [1/s]...): its options class."""
    if contacts == "held":
        given = {name: value for name, value in options.items() if name in METHOD_OPTIONS}
        STABILIZERS.make_options(options.get("method", DEFAULTS["method"]), given)


def _held_system(scene: Scene, contacts: str, options: dict[str, Any]) -> None:
    """The system of held contacts: the ``method`` (and its options) on the ``solver`` (which must take the scene's
    rows), the ``integrator``, automatic gains under error control (``rtol``, ``atol``): ``held_system``."""
    if contacts == "held":
        rtol, atol = options.get("rtol"), options.get("atol")
        integrator = default_integrator(options.get("integrator"), rtol, atol)
        control = None if rtol is None and atol is None else error_control(rtol, atol, integrator)
        given = {name: value for name, value in options.items() if name in METHOD_OPTIONS}
        method = options.get("method", DEFAULTS["method"])
        held_system(scene, method, integrator, options.get("solver"), None, control, given)


def _start(scene: Scene, contacts: str, options: dict[str, Any]) -> None:
    """The start [rad, m; rad/s, m/s] (``start_state``) inside the joint limits (``held_limits``), and assembled:
    the closures of held contacts (``assemble``), or the scene's fit to event-driven (with the limits, its closures
    assembled) or time-stepping contacts (``contact_system``)."""
    q0, v0 = start_state(scene, None, None)
    limits = held_limits(scene, q0)
    if contacts == "held":
        assemble(ConstrainedModel(scene), q0, v0)
    else:
        contact_system(scene, q0, v0, closures=contacts == "event" and bool(limits))


RUN_CHECKS: tuple[tuple[tuple[str, ...], Callable[[Scene, str, dict[str, Any]], dict[str, int] | None]], ...] = (
    (("dt", "duration", "record_every"), _time_grid),
    (("rtol", "atol", "integrator"), _tolerances),
    (("drift_limit",), _drift_limit),
    (("method", *METHOD_OPTIONS), _method_options),
    (("method", "solver", "integrator", "rtol", "atol", *METHOD_OPTIONS), _held_system),
    ((), _start),
)  # (the options a check reads, the check)
