"""The compiled step loop: runs of fixed steps taken in C++ (``pinstab._compiled``, sources in ``cpp/``) on the
native, banded and servo paths.

A Python step on those paths costs the evaluation (Pinocchio's passes, microseconds) plus Python's calls and
NumPy's small-array arithmetic around it (on the four-bar, more than the evaluation itself:
``benchmarks/overhead.py``). :class:`CompiledSteps` hands the stepping loop's runs of steps between its checks to
the compiled loop: the same schemes (:mod:`pinstab.integration.schemes`), the same sums in the same order, the
same evaluations (Pinocchio's ``constraintDynamics`` on the native path, the compiled banded or servo solve on
those paths, which the Python step calls too) at the same stage times: the results equal the Python loop's to the
last bit. The loop's checks, the passage watch, the samples and the fallbacks (a near-singular banded solve, a
servo that loses rank or meets a bound) stay in Python: the compiled loop stops before a step whose evaluation is
not to be used and the Python step takes it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..system import ConstrainedSystem
    from .schemes import Integrator

SCHEMES = {"euler": 0, "semi-implicit-euler": 1, "heun": 2, "rk4": 3}
"""The explicit schemes the compiled loop takes, by name (the codes of ``cpp/kernels.hpp``)."""


def compiled_obstacle(system: ConstrainedSystem, stepper: Integrator) -> str | None:
    """Why the compiled loop cannot take this run's steps (naming the first reason), or None."""
    if system.path not in ("native", "banded", "servo", "core"):
        return f"the {system.path} path (pinstab's KKT backend) runs in Python"
    if stepper.name not in SCHEMES:
        return f"integrator {stepper.name} is not one of {', '.join(SCHEMES)}"
    if system.stabilizer.corrects:
        return f"method {system.stabilizer.name} corrects the state after each step (in Python)"
    if system.path == "core":  # its kernel takes every force (its Python part too) and integrates on the group
        return None
    if system.model.forces:
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
