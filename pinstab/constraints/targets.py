"""Targets that vary in time: named trajectories that scene files give to servo (or closure) targets,
read as data (nothing is evaluated).

A trajectory is a table with a ``kind`` among :data:`TRAJECTORY_KINDS`; its values have the target's size
(1 for a joint relation or a turn angle, 3 for a point) and dimension (length, angle or coordinate):

* ``polynomial``: ``coefficients = [c0, c1, ...]``, x(t) = sum_k c_k t^k; c_k in [X/s^k] (SI), or in
  [unit/s^k] with ``unit`` (e.g. ``"deg"``, ``"mm"``).
* ``sinusoid``: ``offset + amplitude sin(omega t + phase)``; ``omega`` [rad/s] (one rate, or one per axis),
  ``phase`` [rad]; ``offset`` defaults to the target's start value.
* ``minimum-jerk``: from ``from`` (default: the start value) to ``to`` over ``duration`` [s] beginning at
  ``start`` [s] (default 0): ``from + (to - from)(10 s^3 - 15 s^4 + 6 s^5)``, s = (t - start)/duration,
  held before and after.
* ``cubic-spline``: through ``times`` [s] (strictly increasing, at least 2) and ``values``; ``ends =
  "clamped"`` (zero end slopes, the default) or ``"natural"`` (zero end curvature); held outside the times.

Each gives the value and its first and second time derivatives, exactly, evaluated in C++ from its compiled form
(:meth:`TargetTrajectory.compiled`, ``cpp/targets.cpp``: the servo kernel and the relation row read the same). A kind
registered without a compiled form overrides :meth:`TargetTrajectory.evaluate` in Python (its servo then runs on the
general path). Every value lies within
:data:`~pinstab.units.MAX_COORDINATE` [m or rad] (a point's positions and amplitudes also within the scene's reach,
:data:`~pinstab.tables.MAX_REACH` scene sizes), every time within :data:`MAX_TIME` [s], every feature in time (a
move's duration, a spline's interval, a sinusoid's half period) lasts at least :data:`MIN_SPAN` [s], and a
polynomial's coefficients c_k (k >= 1) lie within :data:`~pinstab.units.MAX_MAGNITUDE` (SI), of degree at most
:data:`MAX_DEGREE`: refused by name otherwise, before any work.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from ..errors import SceneError, WaypointError, choices
from ..kernels import CompiledTarget
from ..registry import Registry
from ..tables import check_keys, vector
from ..units import COORDINATE_REASON, MAGNITUDE_REASON, MAX_COORDINATE, MAX_MAGNITUDE, finite_number, quantity

MIN_SPAN = 1e-6  # [s] the shortest feature of a target in time: a move's duration, a spline's interval, a
# sinusoid's half period. Drives' current loops run at 10-100 kHz (10 us and slower); a move of 1 mm in 1 us already
# asks 6e9 m/s^2 (5.77 change / duration^2), and from about 1e-154 s the derivatives overflow
MAX_TIME = 1e9  # [s] (32 years) the latest (or earliest) time a target names: float64 resolves times up to it to
# 1.2e-7 s, finer than MIN_SPAN; beyond, a move's start and end round to the same time
MAX_OMEGA = math.pi / MIN_SPAN  # [rad/s] a sinusoid's half period at least MIN_SPAN
MAX_DEGREE = 15  # a polynomial's: at t = 10 s the terms of degree 0 to 15 span 15 decades, all of float64's digits
# (minimum-snap and minimum-crackle moves are of degree 7 and 9; longer shapes are cubic-spline waypoints)
SPAN_REASON = (
    f"a target's feature in time (a move's duration, a spline's interval, a sinusoid's half period) shorter than "
    f"{MIN_SPAN:g} s is beyond any actuator (current loops run at 10-100 kHz) and its derivatives grow as "
    "1/duration^2, overflowing from about 1e-154 s"
)
TIME_REASON = f"float64 resolves times up to {MAX_TIME:g} s to 1.2e-7 s, finer than a target's shortest feature"
UNIT_NAMES = {"length": "m", "angle": "rad", "coordinate": "m or rad"}  # SI units of a target's dimension


class TargetTrajectory:
    """A target x(t) of ``size`` components [m or rad], with exact time derivatives.

    A kind gives :meth:`compiled` (each component as a sinusoid or a piecewise polynomial) and :meth:`evaluate`
    runs it in C++; a kind registered without one (a user's :data:`TRAJECTORY_KINDS` entry) overrides
    :meth:`evaluate` instead, and its servo runs on the general path.
    """

    size: int

    def evaluate(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, dx/dt, d2x/dt2) at time t [s]: arrays of ``size`` [X, X/s, X/s^2], from the compiled form
        (:attr:`compiled_target`).

        Raises:
            SceneError: the kind has no compiled form and does not override this method.
        """
        return self.compiled_target.evaluate(t)

    @cached_property
    def compiled_target(self) -> CompiledTarget:
        """The compiled form of every component, bound once (``cpp/targets.hpp``'s ``Targets``)."""
        forms = [self.compiled(component) for component in range(self.size)]
        if any(form is None for form in forms):
            raise SceneError(
                f"trajectory {type(self).__name__} has no compiled form (compiled() gives None): a kind without one "
                "overrides evaluate(t) -> (x, dx/dt, d2x/dt2)"
            )
        return CompiledTarget(forms)

    def compiled(self, component: int) -> dict[str, Any] | None:
        """Component ``component`` of the trajectory in the form the compiled core evaluates
        (``cpp/targets.hpp``): ``{"kind": "sinusoid", "wave": [offset, amplitude, omega, phase]}`` or
        ``{"kind": "piecewise", "breaks", "origins", "coefficients" (pieces x (degree + 1), ascending powers of
        (t - origin) / scale), "held", "scale" [s]}``; None (the default) when it has none: it overrides
        :meth:`evaluate`, and its servo runs on the general path."""
        return None


def piecewise(
    breaks: list[float], origins: list[float], coefficients: np.ndarray, held: bool, scale: float = 1.0
) -> dict[str, Any]:
    """A compiled piecewise polynomial (see :meth:`TargetTrajectory.compiled`); ``scale`` [s]: the coefficients'
    unit of time (a move's duration, so that they are of order one)."""
    return {
        "kind": "piecewise",
        "breaks": np.asarray(breaks, dtype=float),
        "origins": np.asarray(origins, dtype=float),
        "coefficients": np.atleast_2d(np.asarray(coefficients, dtype=float)),
        "held": held,
        "scale": float(scale),
    }


def values_at(t: float, value: float, rate: float, curvature: float) -> dict[str, Any]:
    """The compiled form that gives (value, rate, curvature) [X, X/s, X/s^2] at time t [s] exactly (the quadratic
    about t, evaluated at t - t = 0): a target's values from Python handed to a compiled row at t."""
    return piecewise([-np.inf, np.inf], [t], np.array([value, rate, curvature / 2.0]), held=False)


@dataclass(frozen=True)
class TargetContext:
    """What a trajectory reads its table against.

    Attributes:
        size: 1 (a scalar target) or 3 (a point). dimension: the values' quantity (``length``, ``angle`` or
            ``coordinate``). start: the target's value at the scene's initial configuration (size,).
        reach: for a point, the check of a position or an amplitude [m] against the scene's size
            (:meth:`~pinstab.tables.SceneTables.within_reach`), naming ``where``; None: none.
    """

    size: int
    dimension: str
    start: np.ndarray
    reach: Callable[[np.ndarray, str], None] | None = None

    def value(self, raw: Any, where: str) -> np.ndarray:
        """One value of the target: a number (size 1) or a list of 3 (size 3), with units of the dimension
        (:meth:`bounded`)."""
        if self.size == 1:
            return self.bounded(np.array([quantity(raw, self.dimension, where)]), where)
        return self.bounded(vector(raw, self.size, where, self.dimension), where)

    def bounded(self, values: np.ndarray, where: str) -> np.ndarray:
        """``values`` [SI] when within :data:`~pinstab.units.MAX_COORDINATE` [m or rad] and, for a point, the
        scene's reach."""
        within(values, MAX_COORDINATE, where, UNIT_NAMES[self.dimension], COORDINATE_REASON)
        if self.reach is not None:
            self.reach(values, where)
        return values

    def rate(self, raw: Any, dimension: str, where: str) -> np.ndarray:
        """A number for every component, or (size 3) one per component, in ``dimension``."""
        if self.size > 1 and isinstance(raw, list):
            return vector(raw, self.size, where, dimension)
        return np.full(self.size, quantity(raw, dimension, where))


def within(
    values: np.ndarray, bound: float, where: str, unit: str, reason: str, lower: float | None = None
) -> np.ndarray:
    """``values`` [SI] when each lies in [``lower`` (default -bound), ``bound``].

    Raises:
        SceneError: naming the first outside (``where``, or ``where[i]`` of a vector), the allowed range and why.
    """
    low = -bound if lower is None else lower
    outside = np.flatnonzero(~((values >= low) & (values <= bound)))
    if outside.size:
        i = int(outside[0])
        name = where if values.size == 1 else f"{where}[{i}]"
        raise SceneError(
            f"{name} = {values.flat[i]:.3g} {unit} is outside the allowed range [{low:g}, {bound:g}] {unit}: {reason}"
        )
    return values


def instant(raw: Any, where: str) -> float:
    """A time a target names [s]: finite, within +-:data:`MAX_TIME`."""
    return float(within(np.array([quantity(raw, "time", where)]), MAX_TIME, where, "s", TIME_REASON)[0])


TRAJECTORY_KINDS: Registry[TargetTrajectory] = Registry("trajectory kind")
"""Scene-file trajectory kinds: ``kind = NAME`` in a target table. A factory is ``parse(table, context,
where) -> TargetTrajectory``; it names ``where`` in its errors."""


def read_trajectory(entry: Any, context: TargetContext, where: str) -> TargetTrajectory:
    """The trajectory of a scene table ``{ kind = ..., ... }``.

    Raises:
        SceneError: not a table, an unknown kind (the valid kinds listed), or bad keys or values.
        WaypointError: spline waypoints unsorted or of mismatched lengths.
    """
    if not isinstance(entry, dict):
        raise SceneError(f"{where} must be a table {{ kind = ..., ... }}; kinds: {choices(TRAJECTORY_KINDS)}")
    kind = entry.get("kind")
    if kind not in TRAJECTORY_KINDS:
        raise SceneError(f"{where}: unknown trajectory kind {kind!r}; valid kinds: {choices(TRAJECTORY_KINDS)}")
    return TRAJECTORY_KINDS.entry(kind).factory(entry, context, f"{where} ({kind})")


class Polynomial(TargetTrajectory):
    """x(t) = sum_k c_k t^k; ``coefficients`` (degree + 1, size) in [X/s^k]."""

    def __init__(self, coefficients: np.ndarray) -> None:
        self.coefficients = coefficients
        self.size = coefficients.shape[1]

    def compiled(self, component: int) -> dict[str, Any]:
        return piecewise([-np.inf, np.inf], [0.0], self.coefficients[:, component], held=False)


@TRAJECTORY_KINDS.register("polynomial", summary="sum of c_k t^k (coefficients, optional unit)")
def parse_polynomial(entry: dict, context: TargetContext, where: str) -> Polynomial:
    """``coefficients`` (numbers, or lists of 3 for a point), ``unit`` (of the target's dimension)."""
    check_keys(entry, {"kind", "coefficients", "unit"}, where)
    raw = entry.get("coefficients")
    if not isinstance(raw, list) or not raw:
        raise SceneError(f"{where}: 'coefficients' must be a non-empty list [c0, c1, ...] (c_k in unit/s^k)")
    if len(raw) > MAX_DEGREE + 1:
        raise SceneError(
            f"{where}: {len(raw)} coefficients, a polynomial of degree {len(raw) - 1}; at most {MAX_DEGREE + 1} "
            f"(degree {MAX_DEGREE}: beyond, its terms span more decades than float64 has digits); give longer "
            "shapes as cubic-spline waypoints"
        )
    unit = entry.get("unit")
    scale = 1.0 if unit is None else quantity(f"1 {unit}", context.dimension, f"{where}.unit")
    if context.size == 1:
        rows = [[finite_number(c, f"{where}.coefficients[{k}]")] for k, c in enumerate(raw)]
    else:
        rows = [vector(c, context.size, f"{where}.coefficients[{k}]", None) for k, c in enumerate(raw)]
    coefficients = scale * np.array(rows, dtype=float)
    unit_name = UNIT_NAMES[context.dimension]
    context.bounded(coefficients[0], f"{where}.coefficients[0]")
    per = unit_name if " " not in unit_name else f"({unit_name})"
    for k, row in enumerate(coefficients[1:], start=1):
        rate = f"{per}/s" if k == 1 else f"{per}/s^{k}"
        within(row, MAX_MAGNITUDE, f"{where}.coefficients[{k}]", rate, MAGNITUDE_REASON)
    return Polynomial(coefficients)


class Sinusoid(TargetTrajectory):
    """x(t) = offset + amplitude sin(omega t + phase), per component."""

    def __init__(self, offset: np.ndarray, amplitude: np.ndarray, omega: np.ndarray, phase: np.ndarray) -> None:
        self.offset, self.amplitude, self.omega, self.phase = offset, amplitude, omega, phase
        self.size = len(offset)

    def compiled(self, component: int) -> dict[str, Any]:
        wave = (self.offset, self.amplitude, self.omega, self.phase)
        return {"kind": "sinusoid", "wave": np.array([float(part[component]) for part in wave])}


SINUSOID_KEYS = {"amplitude", "omega", "phase", "offset"}


@TRAJECTORY_KINDS.register("sinusoid", summary="offset + amplitude sin(omega t + phase)")
def parse_sinusoid(entry: dict, context: TargetContext, where: str) -> Sinusoid:
    """``amplitude``, ``omega`` [rad/s], ``phase`` [rad], ``offset`` (default: the start value)."""
    check_keys(entry, SINUSOID_KEYS | {"kind"}, where)
    return sinusoid(entry, context, where)


def sinusoid(entry: dict, context: TargetContext, where: str) -> Sinusoid:
    """The sinusoid of a table of :data:`SINUSOID_KEYS` (also the older ``sine = {...}`` forms)."""
    zero = [0.0] * context.size if context.size > 1 else 0.0
    offset = context.value(entry["offset"], f"{where}.offset") if "offset" in entry else context.start
    omega = context.rate(entry.get("omega", 0.0), "angular-velocity", f"{where}.omega")
    phase = context.rate(entry.get("phase", 0.0), "angle", f"{where}.phase")
    return Sinusoid(
        offset,
        context.value(entry.get("amplitude", zero), f"{where}.amplitude"),
        within(omega, MAX_OMEGA, f"{where}.omega", "rad/s", SPAN_REASON),
        within(phase, MAX_COORDINATE, f"{where}.phase", "rad", COORDINATE_REASON),
    )


class MinimumJerk(TargetTrajectory):
    """The quintic of least integrated squared jerk from rest at ``start`` to rest at ``start + duration``."""

    def __init__(self, origin: np.ndarray, goal: np.ndarray, start: float, duration: float) -> None:
        self.origin, self.change, self.start, self.duration = origin, goal - origin, start, duration
        self.size = len(origin)

    def compiled(self, component: int) -> dict[str, Any]:
        change = float(self.change[component])  # in s = (t - start) / duration
        quintic = [float(self.origin[component]), 0.0, 0.0, 10.0 * change, -15.0 * change, 6.0 * change]
        return piecewise([self.start, self.start + self.duration], [self.start], quintic, True, self.duration)


@TRAJECTORY_KINDS.register("minimum-jerk", summary="rest to rest from 'from' to 'to' (start, duration)")
def parse_minimum_jerk(entry: dict, context: TargetContext, where: str) -> MinimumJerk:
    """``to``, ``from`` (default: the start value), ``start`` [s] (default 0), ``duration`` [s] (> 0)."""
    check_keys(entry, {"kind", "from", "to", "start", "duration"}, where)
    if "to" not in entry or "duration" not in entry:
        raise SceneError(f"{where}: 'to' and 'duration' are required ('from' and 'start' are optional)")
    origin = context.value(entry["from"], f"{where}.from") if "from" in entry else context.start
    duration = instant(entry["duration"], f"{where}.duration")
    if not duration > 0:
        raise SceneError(f"{where}.duration must be positive, got {entry['duration']!r}")
    within(np.array([duration]), MAX_TIME, f"{where}.duration", "s", SPAN_REASON, lower=MIN_SPAN)
    start = instant(entry.get("start", 0.0), f"{where}.start")
    return MinimumJerk(origin, context.value(entry["to"], f"{where}.to"), start, duration)


class Spline(TargetTrajectory):
    """A cubic spline through waypoints (scipy's CubicSpline), held at the end values outside them."""

    def __init__(self, times: np.ndarray, values: np.ndarray, ends: str) -> None:
        self.spline = CubicSpline(times, values, axis=0, bc_type=ends)
        self.size = values.shape[1]

    def compiled(self, component: int) -> dict[str, Any]:
        spline = self.spline  # scipy's c: (4, pieces, size), descending powers of t - x_i
        return piecewise(spline.x, spline.x[:-1], spline.c[::-1, :, component].T, held=True)


SPLINE_ENDS = ("clamped", "natural")


@TRAJECTORY_KINDS.register("cubic-spline", summary="cubic spline through waypoints (times, values, ends)")
def parse_spline(entry: dict, context: TargetContext, where: str) -> Spline:
    """``times`` [s] (strictly increasing), ``values`` (one per time), ``ends`` (clamped | natural)."""
    check_keys(entry, {"kind", "times", "values", "ends"}, where)
    times, values = entry.get("times"), entry.get("values")
    if not isinstance(times, list) or not isinstance(values, list):
        raise WaypointError(f"{where}: 'times' and 'values' must be lists (one value per time)")
    if len(times) != len(values) or len(times) < 2:
        raise WaypointError(
            f"{where}: {len(times)} times and {len(values)} values; give as many values as times, at least 2"
        )
    seconds = np.array([instant(x, f"{where}.times[{k}]") for k, x in enumerate(times)])
    backwards = np.flatnonzero(np.diff(seconds) <= 0)
    if backwards.size:
        k = int(backwards[0])
        raise WaypointError(
            f"{where}: times must increase strictly: times[{k + 1}] = {seconds[k + 1]:g} s after "
            f"times[{k}] = {seconds[k]:g} s"
        )
    close = np.flatnonzero(np.diff(seconds) < MIN_SPAN)
    if close.size:
        k = int(close[0])
        raise WaypointError(
            f"{where}: times[{k + 1}] = {seconds[k + 1]:.9g} s is {seconds[k + 1] - seconds[k]:.3g} s after "
            f"times[{k}]; waypoints at least {MIN_SPAN:g} s apart: {SPAN_REASON}"
        )
    ends = entry.get("ends", "clamped")
    if ends not in SPLINE_ENDS:
        raise SceneError(f"{where}.ends: unknown ends {ends!r}; valid: {choices(SPLINE_ENDS)}")
    points = np.array([context.value(x, f"{where}.values[{k}]") for k, x in enumerate(values)])
    return Spline(seconds, points, ends)
