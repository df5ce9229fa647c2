"""A quantity given as a time table: linear between its points, held at its ends, evaluated by the compiled core's
target (``cpp/targets.cpp``), which the core kernel runs too."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import SceneError
from ..kernels import CompiledTarget
from ..tables import SceneTables
from ..units import finite_number


class TimeTable:
    """``values`` at ``times``: linear between the points, held before the first and after the last.

    Args:
        owner: what the table belongs to, for errors (``joint-torque 'motor'``).
        times: [s], strictly increasing (one entry for a constant).
        values: one per time (in the owner's unit).

    Raises:
        SceneError: naming the owner when the lengths differ, the times do not increase, or an entry is not finite.
    """

    def __init__(self, owner: str, times: np.ndarray, values: np.ndarray) -> None:
        times, values = np.array(times, float, ndmin=1), np.array(values, float, ndmin=1)
        if times.shape != values.shape or times.ndim != 1 or times.size == 0:
            raise SceneError(
                f"{owner}: the table needs one value per time, got {times.shape} times and {values.shape} values"
            )
        if not (np.all(np.isfinite(times)) and np.all(np.isfinite(values))):
            raise SceneError(f"{owner}: the table's times and values must be finite")
        if np.any(np.diff(times) <= 0):
            raise SceneError(f"{owner}: the table's times must be strictly increasing")
        times.flags.writeable = values.flags.writeable = False  # an edit in place would not reach the compiled copy
        self.times, self.values = times, values
        self._target = CompiledTarget([self.compiled()])

    def compiled(self) -> dict[str, Any]:
        """The table as a compiled piecewise polynomial (``cpp/targets.hpp``, the form of
        :func:`pinstab.constraints.targets.piecewise`): on [t_i, t_i+1) the line ``values_i + slope_i (t - t_i)``,
        from the last time on its last value (a constant piece), before the first its first value (held)."""
        times, values = self.times, self.values
        slopes = np.diff(values) / np.diff(times)
        coefficients = np.column_stack([values, np.append(slopes, 0.0)])
        breaks = np.append(times, np.inf)
        return {"kind": "piecewise", "breaks": breaks, "origins": times, "coefficients": coefficients, "held": True}

    def __call__(self, t: float) -> float:
        """The value at time ``t`` [s]."""
        return float(self._target.evaluate(t)[0][0])


def read_table(
    entry: dict, tables: SceneTables, constant: str, dimension: str | None, where: str
) -> tuple[np.ndarray, np.ndarray]:
    """(times [s], values) of an entry's ``constant`` (a single value, time 0) or ``table`` ([[t, value], ...]),
    each value a quantity of ``dimension`` (units read by ``tables``; None: a plain number).

    Raises:
        SceneError: both or neither given, a table that is not a list of pairs, a bad quantity (named).
    """
    if (constant in entry) == ("table" in entry):
        raise SceneError(f"{where}: give exactly one of {constant!r} (constant) or 'table' ([[t, {constant}], ...])")

    def value(item: Any, at: str) -> float:
        return finite_number(item, at) if dimension is None else tables.quantity(item, dimension, at)

    if constant in entry:
        return np.zeros(1), np.array([value(entry[constant], f"{where}.{constant}")])
    rows = entry["table"]
    if not isinstance(rows, list) or not rows or not all(isinstance(r, list) and len(r) == 2 for r in rows):
        raise SceneError(f"{where}.table must be a non-empty list of [time, {constant}] pairs")
    times = np.array([tables.quantity(r[0], "time", f"{where}.table time") for r in rows])
    values = np.array([value(r[1], f"{where}.table {constant}") for r in rows])
    return times, values
