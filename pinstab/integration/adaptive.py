"""Error control: an embedded Runge-Kutta pair (``dopri5``: Dormand-Prince 5(4); ``dop853``: 8(5,3))
takes the steps its error estimate allows, and the samples on the user's grid come from the dense output.

Per step, the two solutions of the pair differ by ``h sum_i e_i k_i`` (the stage slopes k_i weighted by
the estimator e): for the configuration this is the difference of the two increments in the tangent space
at the step's start (``pin.difference`` of the two solutions, to second order), for the velocity the plain
difference. Each coordinate is scaled by ``atol + rtol * max(|y0|, |y1|)``, |q| meaning
:meth:`~pinstab.model.ConstrainedModel.magnitude`; the step is accepted when the largest scaled error over
the coordinates is at most 1 (DOP853: Hairer's combination of its 5th- and 3rd-order estimates). The
largest, not the root-mean-square of Hairer's codes and SciPy: a mechanism of many coordinates of which a
few move fast would otherwise dilute their error by the square root of the count (13 at N = 40); on the
four-bar over 10 s, rtol 1e-8 gives 6.7e-7 rad with it, 1.05e-6 with the mean, at 12 % more steps. The next
step is ``h * clip(0.9 err^(-1 / (p + 1)), 0.2, 10)`` (p the estimator's order; no growth right after a
rejection).

Stabilization is applied consistently with the estimate: the error is that of the step of the stabilized
ODE (Baumgarte's term is part of it); a method that corrects the state (``projection``, ``post``) corrects
the accepted solution, after the estimate, and the next step starts from the corrected state. Samples on
the grid are taken from the quintic Hermite interpolant of each accepted step (:mod:`.dense`). Singular
passages are planned as in fixed-step runs, by limiting the step (:meth:`PassageWatch.limit`).

The loop is compiled (``cpp/adaptive.cpp``; the coefficients passed from :mod:`.tableaus` and :mod:`.dense`): the
runs of accepted steps between the passage watch's samples run in C++ altogether
(:class:`~pinstab.integration.compiled.CompiledAdaptive`), with the path's compiled evaluation or the system's own
in Python, called back; the steps Python takes itself (a straddling step of a passage, a step of a method that
corrects the state, a step the compiled evaluation leaves) are one attempt of the same compiled function with the
system's evaluation: the same operations in the same order, the same steps and samples to the last bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import DivergenceError
from ..kernels import AdaptivePair
from .compiled import AdaptiveRun, CompiledAdaptive, python_evaluation
from .dense import HERMITE, Segment
from .implicit import NEWTON_ITERATIONS, newton_figures, newton_kappa
from .passages import HORIZON
from .schemes import TableauScheme
from .stepping import GRID_SLACK, StepLoop

SAFETY = 0.9
MIN_FACTOR, MAX_FACTOR = 0.2, 10.0  # bounds of the step-size change per step
MIN_STEP = 1e-14  # [s per s of simulated time] below this the step cannot advance time reliably
PI_ALPHA, PI_BETA = 0.7, 0.4  # proportional-integral step control (Gustafsson): exponents in units of 1/(p+1)
ESTIMATOR_MIX = 0.01  # DOP853: weight of the 3rd-order estimate in the combined error (Hairer's code)
TOO_SHORT = 3  # AdaptivePair.attempt's outcome: the step fell below MIN_STEP


@dataclass
class ErrorControl:
    """The tolerances and what the control did.

    Attributes:
        rtol: relative tolerance [-]. atol: absolute tolerance [rad, m, rad/s, m/s].
        accepted, rejected: steps. smallest_step, largest_step: of the accepted steps [s].
    """

    rtol: float
    atol: float
    accepted: int = 0
    rejected: int = 0
    smallest_step: float = math.inf
    largest_step: float = 0.0

    def summary(self) -> dict[str, float | int]:
        """The figures a run reports."""
        return {
            "rtol": self.rtol,
            "atol": self.atol,
            "steps_accepted": self.accepted,
            "steps_rejected": self.rejected,
            "smallest_step": float(self.smallest_step) if self.accepted else None,
            "largest_step": float(self.largest_step) if self.accepted else None,
        }


class Attempt(NamedTuple):
    """A step tried: its length [s], end state, stage slopes, the derivative at its end when the estimator
    needs it, and its scaled error [-]."""

    h: float
    q: np.ndarray
    v: np.ndarray
    slopes: np.ndarray
    end_slope: np.ndarray | None
    error: float


class AdaptiveLoop(StepLoop):
    """Steps a bound system with error control; samples on the grid of the run's ``dt`` (the output step).

    Args:
        system, stepper, grid, every, drift_limit, warned: as :class:`StepLoop` (``stepper`` an
            :class:`~pinstab.integration.schemes.TableauScheme` with an error estimator: an explicit pair, or a
            stiffly accurate implicit one whose stages Newton's iteration solves to a share
            (:func:`~pinstab.integration.implicit.newton_kappa`) of the tolerances, a stage it cannot solve rejecting
            the step like an error above 1).
        control: the tolerances, and the counters the loop fills.
    """

    def __init__(self, system, stepper: TableauScheme, grid, every, drift_limit, warned, control: ErrorControl):
        super().__init__(system, stepper, grid, every, drift_limit, warned)
        self.control = control
        self.pair = stepper
        self.exponent = -1.0 / (stepper.tableau.estimator_order + 1)
        constants = {
            "rtol": control.rtol,
            "atol": control.atol,
            "safety": SAFETY,
            "min_factor": MIN_FACTOR,
            "max_factor": MAX_FACTOR,
            "min_step": MIN_STEP,
            "pi_alpha": PI_ALPHA,
            "pi_beta": PI_BETA,
            "estimator_mix": ESTIMATOR_MIX,
            "exponent": self.exponent,
            "newton_kappa": newton_kappa(control.rtol),
            "newton_iterations": NEWTON_ITERATIONS,
        }
        self.rules = AdaptivePair(
            stepper.nodes, stepper.coupling, stepper.weights, stepper.estimators, HERMITE, constants
        )
        self.compiled = CompiledAdaptive.of(system, stepper, self.rules)  # in place of the fixed-step loop
        self.stiff_watch = None  # the control, not a criterion at one step, keeps the steps stable
        self.step_size: float | None = None
        self.previous_error = 1.0  # the last accepted step's error, for the PI control
        self.rejected_last = False  # the last step was accepted after a rejection
        self._start: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # (q, v, a) where the next step starts

    def newton_figures(self) -> dict[str, int] | None:
        """What an implicit pair's Newton iteration did so far (its compiled pair's), None for an explicit one."""
        counts = self.rules.newton
        return None if counts is None else newton_figures(counts)

    def snapshot(self) -> tuple:
        return super().snapshot(), self.step_size, self.previous_error, self._start

    def name_stiff_mode(self, *failure) -> None:
        """Nothing: under error control the grid's dt is the output step, not a step of the scheme a stiff mode
        limits (the controller shortens its steps instead)."""

    def restore(self, state: tuple) -> None:
        base, self.step_size, self.previous_error, self._start = state
        super().restore(base)

    def advance(self, q: np.ndarray, v: np.ndarray, start: int, stop: int) -> tuple[np.ndarray, np.ndarray, int]:
        """Accepted steps from grid step ``start`` to grid step ``stop`` (the last step shortened to end on
        it), the grid samples between them from the dense output."""
        grid, system, watch = self.grid, self.system, self.watch
        t, t_stop = grid.time(start), grid.time(stop)
        a = self._acceleration_at(q, v, t)
        if self.step_size is None:
            self.step_size = self.initial_step(q, v, a, t)
        runs: list[AdaptiveRun] = []  # compiled runs whose grid samples are still to be kept (kept at once)
        try:
            while t < t_stop - GRID_SLACK * grid.dt:
                if t >= watch.next_due:
                    watch.sample(t, q, self.step_size)
                if self.compiled is not None:
                    run = self._compiled_run(t, q, v, a, t_stop)
                    if run.steps:
                        if len(run.qs):
                            runs.append(run)
                        t, q, v, a = run.t, run.q, run.v, run.a
                    self._raise_failure(run.raised, run.too_short, t, q, v)
                    if run.steps:
                        continue
                self._keep_runs(runs)
                proposal = t_stop - t if t_stop - t < self.step_size * (1 + GRID_SLACK) else self.step_size
                h, straddles = watch.limit(t, proposal)
                if straddles and self.guarded:
                    q, v = self.project(q, v, t)
                    a = system.acceleration(q, v, t, 0)
                step = self.attempt(q, v, a, t, h)
                t_new = t + step.h
                q_new, v_new = self.store(step.q, step.v, self.grid_index(t_new), t_new)
                if step.end_slope is not None and q_new is step.q and v_new is step.v:
                    a_new = step.end_slope[system.model.nv :]  # first same as last
                else:
                    a_new = system.acceleration(q_new, v_new, t_new, 0)
                inside = self.grid_between(t, t_new)
                if straddles or inside:
                    segment = Segment(system.model, t, q, v, a, t_new, q_new, v_new, a_new)
                    self._sample_grid(segment, inside, q_new, v_new)
                    if straddles:
                        watch.locate(segment, q, q_new)
                self.step_size = self._next_step(step)
                t, q, v, a = t_new, q_new, v_new, a_new
        finally:
            self._keep_runs(runs)
        self._start = (q, v, a)
        return q, v, stop

    def _compiled_run(self, t: float, q: np.ndarray, v: np.ndarray, a: np.ndarray, t_stop: float) -> AdaptiveRun:
        """Accepted steps from (q, v, a) at t [s] taken by the compiled loop, until ``t_stop`` [s], the passage
        watch's next sample, a step a predicted crossing may shorten, or an attempt left to the Python step (their
        grid samples, of the grid steps after those of the run before, for :meth:`_keep_runs`), or an attempt that
        failed (the run's ``raised`` and ``too_short``); the control's counts and state updated."""
        grid, watch, control = self.grid, self.watch, self.control
        crossing = watch.crossing()
        run = self.compiled.run(
            t,
            q,
            v,
            a,
            self.step_size,
            self.previous_error,
            grid.dt,
            grid.duration,
            grid.steps,
            GRID_SLACK,
            t_stop,
            watch.next_due,
            math.nan if crossing is None else crossing,
            HORIZON,
        )
        self.step_size, self.previous_error = run.step_size, run.previous_error
        control.accepted += run.accepted
        control.rejected += run.rejected
        control.smallest_step = min(control.smallest_step, run.smallest)
        control.largest_step = max(control.largest_step, run.largest)
        return run

    def _keep_runs(self, runs: list[AdaptiveRun]) -> None:
        """Keep the grid samples of compiled runs that followed one another (consecutive grid steps) and empty
        the list."""
        if not runs:
            return
        qs = runs[0].qs if len(runs) == 1 else np.concatenate([run.qs for run in runs])
        vs = runs[0].vs if len(runs) == 1 else np.concatenate([run.vs for run in runs])
        self.records.put_span(runs[0].first, qs, vs)
        if self.limit_watch is not None:
            self.limit_watch.see_span(runs[0].first, qs)
        runs.clear()

    def attempt(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, t: float, h: float) -> Attempt:
        """Steps from (q, v, a) at t [s], shorter after each rejection, until one meets the tolerance; counts
        them (the compiled attempt, ``cpp/adaptive.cpp``, with the system's evaluation).

        A trial step one of whose stages finds a sticking contact outside its cone (a stage of a step too long
        overshoots the state, and the contact forces with it) is rejected like one whose error is not finite.

        Raises:
            DivergenceError: the step fell below :data:`MIN_STEP` (the tolerance cannot be met).
            ContactInfeasibleError: a contact still leaves its cone within a step of :data:`MIN_STEP`.
        """
        system, control = self.system, self.control
        outcome, h, error, rejected, q_new, v_new, slopes, end_slope, raised = self.rules.attempt(
            python_evaluation(system, self.pair.jacobian_kernel()),
            system.model.no_force,
            q,
            v,
            a,
            t,
            h,
        )
        control.rejected += rejected
        self.rejected_last = rejected > 0
        self._raise_failure(raised, h if outcome == TOO_SHORT else math.nan, t, q, v)
        control.accepted += 1
        control.smallest_step = min(control.smallest_step, h)
        control.largest_step = max(control.largest_step, h)
        return Attempt(h, q_new, v_new, slopes, end_slope, error)

    def _raise_failure(
        self, raised: BaseException | None, too_short: float, t: float, q: np.ndarray, v: np.ndarray
    ) -> None:
        """Raise what ended an attempt from (q, v) at t [s]: the exception an evaluation raised, or the
        DivergenceError of a step that fell to ``too_short`` [s] below :data:`MIN_STEP` (NaN: none)."""
        if raised is not None:
            raise raised
        if not math.isnan(too_short):
            control = self.control
            raise DivergenceError(
                f"the error control cannot meet rtol = {control.rtol:g}, atol = {control.atol:g} at t = "
                f"{t:.6g} s: the step fell to {too_short:.3g} s",
                t,
                q,
                v,
                diverged_at=t,
            )

    def _next_step(self, step: Attempt) -> float:
        """The step the estimate asks for [s] after an accepted step: proportional-integral control, at most
        :data:`MAX_FACTOR` times longer (not longer at all right after a rejection), at least MIN_FACTOR times.
        A step shortened for a passage or a chunk's end still tells the right step: the error scales as
        h^(p+1)."""
        following = self.rules.next_step(step.h, step.error, self.step_size, self.previous_error, self.rejected_last)
        self.previous_error = step.error
        return following

    def _acceleration_at(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The acceleration at the state the next step starts from (known when it ends the last step)."""
        if self._start is not None and self._start[0] is q and self._start[1] is v:
            return self._start[2]
        return self.system.acceleration(q, v, t, 0)

    def initial_step(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, t: float) -> float:
        """A first step [s] from the size of the state and of its derivatives (Hairer, Norsett and Wanner,
        Solving ODEs I, II.4), at most the output step."""
        model, control = self.system.model, self.control
        state = np.concatenate((model.magnitude(q), np.abs(v)))
        scale = control.atol + control.rtol * state
        derivative = np.concatenate((v, a))
        with np.errstate(over="ignore"):  # rates beyond floating point: an infinite rate, refused below
            size, rate = _rms(state / scale), _rms(derivative / scale)
        first = 1e-6 if size < 1e-5 or rate < 1e-5 else 0.01 * size / rate
        if not first > 0.0:  # rates beyond floating point (an infinite acceleration): no step can follow them
            raise DivergenceError(
                f"the velocities and accelerations at t = {t:.6g} s are too large for a first step (their size "
                f"{rate:.3g} times rtol, atol): check the scene's forces and initial velocities",
                t,
                q,
                v,
                diverged_at=t,
            )
        q1, v1 = model.integrate(q, first * v), v + first * a
        a1 = self.system.acceleration(q1, v1, t + first, 0)
        curvature = _rms((np.concatenate((v1, a1)) - derivative) / scale) / first
        largest = max(rate, curvature)
        if largest <= 1e-15:
            second = max(1e-6, first * 1e-3)
        else:
            second = (0.01 / largest) ** (1.0 / (self.pair.tableau.order + 1))
        return min(100 * first, second, self.grid.duration)

    def _sample_grid(self, segment: Segment, steps: range, q_end: np.ndarray, v_end: np.ndarray) -> None:
        """Keep the grid samples of ``steps`` (those in (t0, t1] of an accepted step): its end state where a
        grid time falls on it, the dense output elsewhere (corrected like a step's end by methods that
        correct, so that every sample of theirs is on the manifold)."""
        grid, stabilizer = self.grid, self.system.stabilizer
        for k in steps:
            time = grid.time(k)
            if abs(time - segment.t1) <= GRID_SLACK * grid.dt:
                self.keep(k, q_end, v_end)
                continue
            q, v = segment.state(time)
            if stabilizer.corrects:
                correction = stabilizer.correct(self.system.model, self.system.projector, q, v, time)
                q, v = correction.q, correction.v
            self.keep(k, q, v)


def _rms(values: np.ndarray) -> float:
    return float(np.linalg.norm(values)) / math.sqrt(len(values)) if len(values) else 0.0
