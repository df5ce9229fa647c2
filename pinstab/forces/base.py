"""Force elements: what they provide, and the registry of force kinds scene files name."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping
from typing import Any, NamedTuple

import numpy as np

from ..errors import SceneError
from ..kinematics import Kinematics
from ..registry import Registry
from ..tables import length

# [N or N m]: the largest applied force or torque a scene may give: a meganewton, a heavy press's force or a large
# rocket engine's thrust (a ship engine's torque, 1e6 N m), 1e5 times a 1 kg body's weight. Measured on box-push
# (1 kg on four corners) pressed into its table: event-driven contacts hold 3e6 N and stall from 1e7 N (their force
# slacks grow with the force); at 1e200 N an event-driven run's first step was 0 s (ZeroDivisionError)
MAX_LOAD = 1e6
LOAD_REASON = (
    "a meganewton is a heavy press's force or a large rocket engine's thrust, 1e5 times a 1 kg body's weight; "
    "past it the contact solvers' force tolerances swamp the weights and stall"
)


def bounded_load(values: np.ndarray, where: str, unit: str) -> np.ndarray:
    """An applied force, moment or torque ``values`` [N or N m] when its magnitude (a vector's length) is at most
    :data:`MAX_LOAD`.

    Raises:
        SceneError: naming ``where`` (``|forces 'push'.force|``), the magnitude and the allowed range.
    """
    magnitude = length(values)  # beyond floating point: infinite, refused
    if not magnitude <= MAX_LOAD:
        raise SceneError(
            f"|{where}| = {magnitude:.6g} {unit} is outside the allowed range [0, {MAX_LOAD:.0e}] {unit}: {LOAD_REASON}"
        )
    return values


class Sample(NamedTuple):
    """One recorded sample of a run, as :meth:`ForceElement.run_figures` reads it.

    Attributes:
        kin: kinematics updated (placements, Jacobians, velocities) at the sample's state. v: its velocity.
        t: its time [s]. multipliers: the constraint multipliers by block name [N, N m] (NaN where the
            run's dynamics had no solution).
    """

    kin: Kinematics
    v: np.ndarray
    t: float
    multipliers: dict[str, np.ndarray]


class ForceElement(ABC):
    """Something that adds a generalized force and possibly potential energy.

    Attributes:
        name: unique name.
        needs_kinematics: whether :meth:`generalized_force` reads frame placements or Jacobians
            (False lets a solver that computes its own kinematics skip pinstab's pass).
    """

    name: str
    needs_kinematics: bool = True
    switches: bool = False  # whether it switches at events an event-driven run locates (switch_value, switch)

    @abstractmethod
    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        """Generalized force [N, N m] (nv,); needs placements and Jacobians current."""

    def restart(self) -> None:
        """A run starts: forget what an earlier run left in the element (the default keeps nothing)."""
        return None

    def watch(self) -> None:
        """An event-driven run locates this element's switches from now on (until :meth:`restart`); the default: it
        has none."""
        return None

    def switch_value(self, q: np.ndarray, t: float) -> float | None:
        """An element that :attr:`switches`: its event function at (q, t) [s] from its last evaluation, below zero once
        it must switch; None when that evaluation was at another state (the event loop evaluates it at (q, t) and asks
        again). The default: inf, it never switches."""
        return math.inf

    def switch(self, t: float) -> str | None:
        """Switch at the event located at t [s] when the element's event function is below zero there; the event's
        cause in words, else None (the default: nothing to switch)."""
        return None

    @classmethod
    def batch(cls, elements: list[ForceElement]) -> ForceElement | None:
        """One element whose generalized force is the sum of ``elements``' (all of this class), evaluated in one call
        (:func:`batched`); None (the default): the class has no such form, each element is evaluated on its own."""
        return None

    def compiled_form(self, rows: Mapping[str, slice]) -> dict[str, Any] | None:
        """The element as the compiled core takes it (``cpp/core_kernel.hpp``, ``cpp/grasp_forces.hpp``,
        ``cpp/spring_damper.hpp``: a dict with ``kind`` ``joint-spring``, ``hold``, ``wrench``, ``spring-damper`` or
        ``joint-torque``),
        given each constraint's rows in the stack by name
        (``ConstraintSet.slices``); None (the default): it has none, and an evaluation computes it in Python."""
        return None

    def potential_energy(self, kin: Kinematics) -> float:
        """Stored energy [J]; zero for non-conservative elements."""
        return 0.0

    @property
    def stores_energy(self) -> bool:
        """Whether :meth:`potential_energy` can be non-zero (a spring); False by default: the element stores none,
        and a run's energy series is the mechanism's alone."""
        return False

    def power(self, kin: Kinematics, v: np.ndarray, t: float) -> float:
        """Power [W] of the element's non-conservative part, ``tau . v + dV/dt`` (V: :meth:`potential_energy`);
        all of ``tau . v`` for an element that stores none. Needs placements and Jacobians current."""
        return float(self.generalized_force(kin, v, t) @ v)

    def run_figures(self, samples: Iterator[Sample]) -> dict[str, Any]:
        """The figures this element reports on a run (``pinstab run``), read from the run's samples (a
        controller's tracking error, say); none by default, without reading the samples."""
        return {}


def batched(elements: list[ForceElement]) -> list[ForceElement]:
    """``elements`` with those of each class that evaluates many at once (:meth:`ForceElement.batch`) replaced by one
    such evaluation, in the place of the first of them: the same sum of generalized forces [N, N m] in fewer calls (to
    the bit while no other element acts on a coordinate one of them acts on)."""
    classes: dict[type, list[ForceElement]] = {}
    for element in elements:
        classes.setdefault(type(element), []).append(element)
    batches = {kind: kind.batch(members) for kind, members in classes.items() if len(members) > 1}
    evaluated = []
    for element in elements:
        batch = batches.get(type(element))
        if batch is None:
            evaluated.append(element)
        elif element is classes[type(element)][0]:
            evaluated.append(batch)
    return evaluated


FORCE_KINDS: Registry[ForceElement] = Registry("force kind")
"""Scene-file force kinds: ``kind = NAME`` in ``[[forces]]``. A factory is
``parse(table, tables, name, where) -> ForceElement`` reading its own keys through
:class:`~pinstab.tables.SceneTables`."""
