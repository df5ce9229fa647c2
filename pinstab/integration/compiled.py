"""The compiled step loop: runs of steps taken in C++ (``pinstab._compiled``, sources in ``cpp/``) on every path.

A Python step costs the evaluation plus a Python call per stage around it (on the four-bar, more than the
evaluation itself: ``benchmarks/overhead.py``). :class:`CompiledSteps` hands the stepping loop's runs of steps between
its checks to the compiled loop: the same step function as the Python loop's (``SchemeStep``, ``cpp/stepping.cpp``:
:mod:`pinstab.integration.schemes` calls it), the same evaluations at the same stage times: the results equal the
Python loop's to the last bit. The evaluation is the path's compiled kernel (Pinocchio's ``constraintDynamics`` on
the native path, the compiled banded, servo or core solve) where :func:`kernel_obstacle` names no reason, else the
system's own in Python (``system.acceleration``: the general path's KKT solve, a Python stabilizer's term, a compiled
path's fallbacks), called back from the C++ loop (``cpp/callback_kernel.cpp``). On the core path the corrections of
``projection`` and ``post`` are made in the loop after each step (:meth:`ProjectingStabilizer.loop_correction
<pinstab.stabilizers.projection.ProjectingStabilizer.loop_correction>`: the core's rows in C++); elsewhere such a
method keeps the Python loop. The loop's checks, the passage watch, the samples and the fallbacks (a near-singular
banded solve, a servo that loses rank or meets a bound) stay in Python: the compiled loop stops before a step whose
compiled evaluation is not to be used, whose Python evaluation raised or whose correction cannot be made, and the
Python step takes it (or the exception is raised there).

:class:`CompiledAdaptive` does the same for error-controlled runs (``--rtol``, :mod:`pinstab.integration.adaptive`):
the embedded pair's attempts (accept, reject, retry), its error norm, the step-size control and the grid samples from
the dense output on the configuration group in C++ (``cpp/adaptive.cpp``; the coefficients passed from
:mod:`pinstab.integration.tableaus` and :mod:`pinstab.integration.dense`), the functions the Python adaptive loop's
own steps call: the results equal the Python loop's to the last bit (``tests/test_compiled_adaptive.py``). It hands
back to Python at the chunk's end, where the passage watch samples, before a step that a predicted singular crossing
may shorten, and before an attempt the compiled kernel cannot finish (an evaluation not to be used, an error that is
not finite, a step below the smallest).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from ..errors import ContactInfeasibleError
from ..kernels import SchemeStep
from ..projection import compiled_projections
from ..stabilizers.projection import ProjectingStabilizer
from .implicit import ImplicitRungeKutta
from .schemes import SCHEMES, TableauScheme

if TYPE_CHECKING:
    from ..kernels import AdaptivePair, Kernel
    from ..system import ConstrainedSystem
    from .schemes import Integrator


def compiled_obstacle(system: ConstrainedSystem, stepper: Integrator, adaptive: bool = False) -> str | None:
    """Why the compiled loop cannot take this run's steps (naming the first reason), or None; ``adaptive``: the
    error-controlled steps of an embedded pair (:class:`CompiledAdaptive`), else fixed steps of :data:`SCHEMES`."""
    if not adaptive and stepper.name not in SCHEMES and not isinstance(stepper, TableauScheme):
        return f"integrator {stepper.name} is neither one of {', '.join(SCHEMES)} nor a Runge-Kutta tableau"
    stabilizer = system.stabilizer
    if stabilizer.corrects and not (
        isinstance(stabilizer, ProjectingStabilizer) and compiled_projections(system.projector) is not None
    ):
        return f"method {stabilizer.name} corrects the state after each step (compiled on the core path only)"
    if stabilizer.corrects and adaptive:
        return f"method {stabilizer.name} corrects the accepted steps of error control (in Python)"
    return None


def kernel_obstacle(system: ConstrainedSystem) -> str | None:
    """Why the compiled loop evaluates this system in Python (``system.acceleration``, called back from C++) rather
    than with its compiled kernel (naming the first reason), or None."""
    if system.path not in ("native", "banded", "servo", "core"):
        return f"the {system.path} path (pinstab's KKT backend) runs in Python"
    if system.path == "core":  # its kernel takes every force (its Python part too) and steps on the group
        return None
    if system.path == "native" and system.native.force_obstacle is not None:
        return system.native.force_obstacle
    if system.path != "native" and system.model.forces:
        return f"the scene has force elements (the compiled {system.path} kernel takes none)"
    if not system.model.euclidean:
        return "a joint with more than one configuration coordinate (the kernel's loop adds q + dt v)"
    return None


class CompiledLoop:
    """The evaluation of a run's compiled loop: the system's compiled kernel when :func:`kernel_obstacle` names no
    reason and the system lends it (:meth:`ConstrainedSystem.compiled_kernel`), else its Python evaluation.

    Attributes:
        steps: steps (accepted steps) taken by the compiled loop with the compiled kernel so far.
        callback_steps: ... with the Python evaluation.
    """

    def __init__(self, system: ConstrainedSystem) -> None:
        self.system = system
        self.compiled = kernel_obstacle(system) is None
        self.group = None if system.model.euclidean else system.model.model
        self.steps = 0
        self.callback_steps = 0

    def lend_jacobians(self, stepper: Integrator) -> None:
        """An implicit stepper's own steps (the Python step path) take their Newton Jacobians from the kernel this loop
        steps with (:meth:`kernel`: its analytic derivatives, or differences of its evaluation), as the loop's do."""
        if isinstance(stepper, ImplicitRungeKutta):
            stepper.jacobian_kernel = self.kernel

    def kernel(self) -> Kernel | None:
        """The compiled kernel to step with now, or None: the system's Python evaluation."""
        return self.system.compiled_kernel() if self.compiled else None


class CompiledSteps(CompiledLoop):
    """Fixed steps of the compiled loop (``cpp/stepping.cpp``: a scheme's, or a tableau's as
    :meth:`TableauScheme.step` takes them; an implicit one's on the stepper's own compiled step, whose Newton state
    its Python steps share).

    Args:
        system: the bound system. stepper: its integrator (one of :data:`SCHEMES`, or a
            :class:`~pinstab.integration.schemes.TableauScheme`).
    """

    def __init__(self, system: ConstrainedSystem, stepper: Integrator) -> None:
        super().__init__(system)
        self.stages = stepper.stages
        self.implicit = isinstance(stepper, ImplicitRungeKutta)
        if self.implicit:
            self.step = stepper.compiled
        elif isinstance(stepper, TableauScheme):
            self.step = stepper.compiled_tableau(self.group)
        else:
            self.step = SchemeStep(SCHEMES[stepper.name], self.group)
        stabilizer = system.stabilizer  # a method that corrects: on the core's compiled projections (the obstacle)
        self.corrector = (
            stabilizer.loop_correction(system.model, system.projector)
            if isinstance(stabilizer, ProjectingStabilizer)
            else None
        )

    @classmethod
    def of(cls, system: ConstrainedSystem, stepper: Integrator) -> CompiledSteps | None:
        """The compiled steps of this run, or None when :func:`compiled_obstacle` names a reason."""
        if compiled_obstacle(system, stepper) is not None:
            return None
        loop = cls(system, stepper)
        loop.lend_jacobians(stepper)
        return loop

    def run(
        self, q: np.ndarray, v: np.ndarray, start: int, dt: float, steps: int
    ) -> tuple[np.ndarray, np.ndarray, int, BaseException | None, np.ndarray | None]:
        """Up to ``steps`` steps of ``dt`` [s] from (q, v) at grid step ``start`` (time ``start * dt``): the states
        after each (rows, corrected by a method that corrects: :attr:`corrector`), the number done, fewer when the
        next step's compiled evaluation is not to be used (a near-singular banded solve, a servo that loses rank or
        meets a bound), its Python evaluation raised or its correction cannot be made (the Python step takes it and
        says why), that exception (for the caller to raise once it has kept the steps done; else None), and the
        corrections' iterations per step done (None for a method that does not correct)."""
        kernel = self.kernel()
        evaluation = python_evaluation(self.system) if kernel is None else kernel
        before = self.step.newton[0] if self.implicit else 0
        qs, vs, done, raised, iterations = self.step.run(
            evaluation, q, v, self.system.model.no_force, dt, steps, start, self.corrector
        )
        if kernel is None:
            self.callback_steps += done
        else:  # an implicit step: its first stage and its Newton iterations
            newton = self.step.newton[0] - before if self.implicit else done * (self.stages - 1)
            self.system.count_compiled(done + newton)
            self.steps += done
        return qs, vs, done, raised, iterations


class CompiledAdaptive(CompiledLoop):
    """The compiled error-controlled loop of a run (:class:`~pinstab.kernels.AdaptivePair`, built by
    :class:`~pinstab.integration.adaptive.AdaptiveLoop`).

    Args:
        system: the bound system. pair: the pair and the control's constants in compiled form.
    """

    def __init__(self, system: ConstrainedSystem, pair: AdaptivePair) -> None:
        super().__init__(system)
        self.pair = pair

    @classmethod
    def of(cls, system: ConstrainedSystem, stepper: Integrator, pair: AdaptivePair) -> CompiledAdaptive | None:
        """The compiled loop of this run, or None when :func:`compiled_obstacle` names a reason."""
        if compiled_obstacle(system, stepper, adaptive=True) is not None:
            return None
        loop = cls(system, pair)
        loop.lend_jacobians(stepper)
        return loop

    def run(self, *arguments: Any) -> AdaptiveRun:
        """:meth:`AdaptivePair.run <pinstab.kernels.AdaptivePair.run>` under the scene's applied forces (none) on the
        system's compiled kernel (its evaluations counted), or on its Python evaluation."""
        kernel = self.kernel()
        if kernel is None:
            run = AdaptiveRun(*self.pair.run(python_evaluation(self.system), self.system.model.no_force, *arguments))
            self.callback_steps += run.steps
            return run
        run = AdaptiveRun(*self.pair.run(kernel, self.system.model.no_force, *arguments))
        self.system.count_compiled(run.evaluations)
        self.steps += run.steps
        return run


def python_evaluation(system: ConstrainedSystem, jacobian: Kernel | None = None) -> tuple:
    """The system's Python evaluation as the compiled loops take it: (acceleration, the group's pin.Model or None,
    the exceptions that refuse a trial's state: a contact leaving its cone, a step the error control shortens, the
    compiled kernel whose Jacobians an implicit stage's Newton iteration takes or None: differences of acceleration)."""
    group = None if system.model.euclidean else system.model.model
    return (system.acceleration, group, ContactInfeasibleError, jacobian)


class AdaptiveRun(NamedTuple):
    """What a compiled error-controlled run did: its accepted ``steps``, the state it reached (t [s], q, v, a) and
    the controller's (``step_size`` [s], ``previous_error`` [-]), its counts (accepted and rejected steps,
    evaluations, smallest and largest accepted step [s]), the grid samples of grid steps first, first + 1, ...
    (rows of qs, vs), and how a run of the Python evaluation failed: ``too_short``, the step [s] the control fell to
    below the smallest (else NaN), ``raised``, the exception an evaluation raised (else None)."""

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
    too_short: float
    raised: BaseException | None


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
