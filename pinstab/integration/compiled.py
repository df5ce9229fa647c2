"""The compiled step loop: runs of fixed steps taken in C++ (``pinstab._compiled``, sources in ``cpp/``) on the
native, banded and servo paths.

A Python step on those paths costs the evaluation (Pinocchio's passes, microseconds) plus a Python call per stage
around it (on the four-bar, more than the evaluation itself: ``benchmarks/overhead.py``). :class:`CompiledSteps`
hands the stepping loop's runs of steps between its checks to the compiled loop: the same step function as the
Python loop's (``SchemeStep``, ``cpp/stepping.cpp``: :mod:`pinstab.integration.schemes` calls it), the same
evaluations (Pinocchio's ``constraintDynamics`` on the native path, the compiled banded or servo solve on
those paths, which the Python step calls too) at the same stage times: the results equal the Python loop's to the
last bit. The loop's checks, the passage watch, the samples and the fallbacks (a near-singular banded solve, a
servo that loses rank or meets a bound) stay in Python: the compiled loop stops before a step whose evaluation is
not to be used and the Python step takes it.

:class:`CompiledAdaptive` does the same for error-controlled runs (``--rtol``, :mod:`pinstab.integration.adaptive`)
on models whose joints all have one coordinate: the embedded pair's trial steps, its error norm, the step-size
control and the grid samples from the dense output in C++ (``cpp/adaptive.cpp``; the coefficients passed from
:mod:`pinstab.integration.tableaus` and :mod:`pinstab.integration.dense`), the same functions the Python adaptive
loop calls with its own evaluation per stage: the results equal the Python loop's to the last bit
(``tests/test_compiled_adaptive.py``). It hands back to Python at the chunk's end, where the passage watch samples,
before a step that a predicted singular crossing may shorten, and before an attempt it cannot finish (an evaluation
not to be used, an error that is not finite, a step below the smallest).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .schemes import SCHEMES

if TYPE_CHECKING:
    from ..kernels import AdaptivePair
    from ..system import ConstrainedSystem
    from .schemes import Integrator


def compiled_obstacle(system: ConstrainedSystem, stepper: Integrator, adaptive: bool = False) -> str | None:
    """Why the compiled loop cannot take this run's steps (naming the first reason), or None; ``adaptive``: the
    error-controlled steps of an embedded pair (:class:`CompiledAdaptive`), else fixed steps of :data:`SCHEMES`."""
    if system.path not in ("native", "banded", "servo", "core"):
        return f"the {system.path} path (pinstab's KKT backend) runs in Python"
    if not adaptive and stepper.name not in SCHEMES:
        return f"integrator {stepper.name} is not one of {', '.join(SCHEMES)}"
    if system.stabilizer.corrects:
        return f"method {system.stabilizer.name} corrects the state after each step (in Python)"
    takes_forces = system.path == "core"  # its kernel takes every force (its Python part too)
    if takes_forces and not adaptive:  # and its fixed steps integrate on the configuration group
        return None
    if system.model.forces and not takes_forces:
        return "the scene has force elements (the compiled loop takes none)"
    if not system.model.euclidean:
        return "a joint with more than one configuration coordinate (the compiled loop adds q + dt v)"
    return None


class CompiledSteps:
    """Steps of the system's compiled kernel (:meth:`ConstrainedSystem.compiled_kernel`).

    Args:
        system: the bound system. stepper: its integrator (one of :data:`SCHEMES`).

    Attributes:
        steps: steps taken by the compiled loop so far.
    """

    def __init__(self, system: ConstrainedSystem, stepper: Integrator) -> None:
        self.system = system
        self.scheme = SCHEMES[stepper.name]
        self.stages = stepper.stages
        self.steps = 0

    @classmethod
    def of(cls, system: ConstrainedSystem, stepper: Integrator) -> CompiledSteps | None:
        """The compiled steps of this run, or None when :func:`compiled_obstacle` names a reason."""
        return None if compiled_obstacle(system, stepper) is not None else cls(system, stepper)

    def run(
        self, q: np.ndarray, v: np.ndarray, start: int, dt: float, steps: int
    ) -> tuple[np.ndarray, np.ndarray, int] | None:
        """Up to ``steps`` steps of ``dt`` [s] from (q, v) at grid step ``start`` (time ``start * dt``): the states
        after each (rows) and the number done, fewer when the next step's evaluation is not to be used (a
        near-singular banded solve, a servo that loses rank or meets a bound); None while the system's solves must
        be checked one by one (the native path after a failed check)."""
        kernel = self.system.compiled_kernel()
        if kernel is None:
            return None
        qs, vs, done = kernel.run(self.scheme, q, v, self.system.model.no_force, dt, steps, start)
        self.system.count_compiled(done * self.stages)
        self.steps += done
        return qs, vs, done


class CompiledAdaptive:
    """The compiled error-controlled loop of a run (:class:`~pinstab.kernels.AdaptivePair`, built by
    :class:`~pinstab.integration.adaptive.AdaptiveLoop`) over the system's compiled kernel.

    Args:
        system: the bound system. pair: the pair and the control's constants in compiled form.

    Attributes:
        steps: accepted steps taken by the compiled loop so far.
    """

    def __init__(self, system: ConstrainedSystem, pair: AdaptivePair) -> None:
        self.system = system
        self.pair = pair
        self.steps = 0

    @classmethod
    def of(cls, system: ConstrainedSystem, stepper: Integrator, pair: AdaptivePair) -> CompiledAdaptive | None:
        """The compiled loop of this run, or None when :func:`compiled_obstacle` names a reason."""
        return None if compiled_obstacle(system, stepper, adaptive=True) is not None else cls(system, pair)

    def run(self, *arguments: Any) -> AdaptiveRun | None:
        """:meth:`AdaptivePair.run <pinstab.kernels.AdaptivePair.run>` on the system's kernel under the scene's
        applied forces (none), its evaluations counted; None while the system's solves must be checked one by one
        (the native path after a failed check)."""
        kernel = self.system.compiled_kernel()
        if kernel is None:
            return None
        run = AdaptiveRun(*self.pair.run(kernel, self.system.model.no_force, *arguments))
        self.system.count_compiled(run.evaluations)
        self.steps += run.steps
        return run


class AdaptiveRun(NamedTuple):
    """What a compiled error-controlled run did: its accepted ``steps``, the state it reached (t [s], q, v, a) and
    the controller's (``step_size`` [s], ``previous_error`` [-]), its counts (accepted and rejected steps,
    evaluations, smallest and largest accepted step [s]) and the grid samples of grid steps first, first + 1, ...
    (rows of qs, vs)."""

    steps: int
    t: float
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    step_size: float
    previous_error: float
    accepted: int
    rejected: int
    evaluations: int
    smallest: float
    largest: float
    first: int
    qs: np.ndarray
    vs: np.ndarray


def steps_before(k: int, stop: int, dt: float, due: float) -> int:
    """How many steps from grid step k, before step ``stop``, start before the time ``due`` [s] (a step from
    step j starts at j dt)."""
    if not due < math.inf:
        return stop - k
    count = min(max(math.ceil(due / dt) - k, 0), stop - k)
    while count < stop - k and (k + count) * dt < due:
        count += 1
    while count > 0 and (k + count - 1) * dt >= due:
        count -= 1
    return count
