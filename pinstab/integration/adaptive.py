"""Error control: an embedded Runge-Kutta pair (``dopri5``: Dormand-Prince 5(4); ``dop853``: 8(5,3))
takes the steps its error estimate allows, and the samples on the user's grid come from the dense output.

Per step, the two solutions of the pair differ by ``h sum_i e_i k_i`` (the stage slopes k_i weighted by
the estimator e): for the configuration this is the difference of the two increments in the tangent space
at the step's start (``pin.difference`` of the two solutions, to second order), for the velocity the plain
difference. Each coordinate is scaled by ``atol + rtol * max(|y0|, |y1|)``, |q| meaning
:meth:`~pinstab.model.ConstrainedModel.magnitude`; the step is accepted when the root-mean-square of the
scaled error is at most 1 (DOP853: Hairer's combination of its 5th- and 3rd-order estimates), and the next
step is ``h * clip(0.9 err^(-1 / (p + 1)), 0.2, 10)`` (p the estimator's order; no growth right after a
rejection).

Stabilization is applied consistently with the estimate: the error is that of the step of the stabilized
ODE (Baumgarte's term is part of it); a method that corrects the state (``projection``, ``post``) corrects
the accepted solution, after the estimate, and the next step starts from the corrected state. Samples on
the grid are taken from the quintic Hermite interpolant of each accepted step (:mod:`.dense`). Singular
passages are planned as in fixed-step runs, by limiting the step (:meth:`PassageWatch.limit`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import DivergenceError
from .dense import Segment
from .schemes import ExplicitRungeKutta
from .stepping import GRID_SLACK, StepLoop

SAFETY = 0.9
MIN_FACTOR, MAX_FACTOR = 0.2, 10.0  # bounds of the step-size change per step
MIN_STEP = 1e-14  # [s per s of simulated time] below this the step cannot advance time reliably
ESTIMATOR_MIX = 0.01  # DOP853: weight of the 3rd-order estimate in the combined error (Hairer's code)


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
            "smallest_step": self.smallest_step if self.accepted else None,
            "largest_step": self.largest_step if self.accepted else None,
        }


class AdaptiveLoop(StepLoop):
    """Steps a bound system with error control; samples on the grid of the run's ``dt`` (the output step).

    Args:
        system, stepper, grid, every, drift_limit, warned: as :class:`StepLoop` (``stepper`` an
            :class:`ExplicitRungeKutta` with an error estimator).
        control: the tolerances, and the counters the loop fills.
    """

    def __init__(self, system, stepper: ExplicitRungeKutta, grid, every, drift_limit, warned, control: ErrorControl):
        super().__init__(system, stepper, grid, every, drift_limit, warned)
        self.control = control
        self.pair = stepper
        self.needs_end = bool(np.any(stepper.estimators[:, -1]))  # the estimator weighs the new point's slope
        self.exponent = -1.0 / (stepper.tableau.estimator_order + 1)
        self.step_size: float | None = None
        self._start: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # (q, v, a) where the next step starts

    def snapshot(self) -> tuple:
        return super().snapshot(), self.step_size, self._start

    def restore(self, state: tuple) -> None:
        base, self.step_size, self._start = state
        super().restore(base)

    def advance(self, q: np.ndarray, v: np.ndarray, start: int, stop: int) -> tuple[np.ndarray, np.ndarray, int]:
        """Accepted steps from grid step ``start`` to grid step ``stop`` (the last step shortened to end on
        it), the grid samples between them from the dense output."""
        grid, system, watch, control = self.grid, self.system, self.watch, self.control
        t, t_stop = grid.time(start), grid.time(stop)
        a = self._acceleration_at(q, v, t)
        if self.step_size is None:
            self.step_size = self.initial_step(q, v, a, t)
        grown = True  # the step may grow after this one (not right after a rejection)
        while t < t_stop - GRID_SLACK * grid.dt:
            if t >= watch.next_due:
                watch.sample(t, q, self.step_size)
            proposal = min(self.step_size, t_stop - t)
            if t_stop - t - proposal < GRID_SLACK * grid.dt:
                proposal = t_stop - t
            h, straddles = watch.limit(t, proposal)
            if straddles and self.guarded:
                q, v = self.project(q, v, t)
                a = system.acceleration(q, v, t, 0)
            q_new, v_new, slopes = self.pair.attempt(q, v, t, h, a)
            end_slope = self._end_slope(q, q_new, v_new, t + h) if self.needs_end else None
            error = self.error_norm(q, v, q_new, v_new, slopes, end_slope, h)
            if not error <= 1.0:
                control.rejected += 1
                factor = MIN_FACTOR if not math.isfinite(error) else max(MIN_FACTOR, SAFETY * error**self.exponent)
                self.step_size = h * factor
                grown = False
                if self.step_size < MIN_STEP * max(1.0, t):
                    raise DivergenceError(
                        f"the error control cannot meet rtol = {control.rtol:g}, atol = {control.atol:g} at t = "
                        f"{t:.6g} s: the step fell to {self.step_size:.3g} s",
                        t,
                        q,
                        v,
                        diverged_at=t,
                    )
                continue
            control.accepted += 1
            control.smallest_step = min(control.smallest_step, h)
            control.largest_step = max(control.largest_step, h)
            t_new = t + h
            q_corrected, v_corrected = self.store(q_new, v_new, self.grid_index(t_new), t_new)
            unchanged = q_corrected is q_new and v_corrected is v_new
            if end_slope is not None and unchanged:
                a_new = end_slope[system.model.nv :]
            else:
                a_new = system.acceleration(q_corrected, v_corrected, t_new, 0)
            segment = Segment(system.model, t, q, v, a, t_new, q_corrected, v_corrected, a_new)
            self._sample_grid(segment, q_corrected, v_corrected)
            if straddles:
                watch.locate(segment, q, q_corrected)
            # the step the estimate asks for (also after a step shortened for a passage or a chunk's end:
            # the error scales as h^(p+1)), growing at most MAX_FACTOR times, and not right after a rejection
            limited = h < self.step_size * (1.0 - 1e-12)
            optimal = math.inf if error == 0.0 else h * SAFETY * error**self.exponent
            growth = (self.step_size if limited else h) * (MAX_FACTOR if grown else 1.0)
            self.step_size = min(max(optimal, MIN_FACTOR * h), growth)
            grown = True
            t, q, v, a = t_new, q_corrected, v_corrected, a_new
        self._start = (q, v, a)
        return q, v, stop

    def _acceleration_at(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """The acceleration at the state the next step starts from (known when it ends the last step)."""
        if self._start is not None and self._start[0] is q and self._start[1] is v:
            return self._start[2]
        return self.system.acceleration(q, v, t, 0)

    def _end_slope(self, q: np.ndarray, q_new: np.ndarray, v_new: np.ndarray, t: float) -> np.ndarray:
        """The derivative at the new point, in the start's tangent space: [velocity slope | acceleration]."""
        return np.concatenate((self.pair.slope(q, q_new, v_new), self.system.acceleration(q_new, v_new, t, 0)))

    def error_norm(
        self,
        q: np.ndarray,
        v: np.ndarray,
        q_new: np.ndarray,
        v_new: np.ndarray,
        slopes: np.ndarray,
        end_slope: np.ndarray | None,
        h: float,
    ) -> float:
        """The scaled root-mean-square error of a step [-] (accept at <= 1)."""
        model, control = self.system.model, self.control
        scale = control.atol + control.rtol * np.concatenate(
            (np.maximum(model.magnitude(q), model.magnitude(q_new)), np.maximum(np.abs(v), np.abs(v_new)))
        )
        stages = slopes.shape[0]
        estimates = [row[:stages] @ slopes for row in self.pair.estimators]
        if end_slope is not None:
            estimates = [e + row[stages] * end_slope for e, row in zip(estimates, self.pair.estimators, strict=True)]
        if len(estimates) == 1:
            return abs(h) * float(np.linalg.norm(estimates[0] / scale)) / math.sqrt(len(scale))
        fifth, third = (float(np.sum((estimate / scale) ** 2)) for estimate in estimates)
        if fifth == 0.0 and third == 0.0:
            return 0.0
        return abs(h) * fifth / math.sqrt((fifth + ESTIMATOR_MIX * third) * len(scale))

    def initial_step(self, q: np.ndarray, v: np.ndarray, a: np.ndarray, t: float) -> float:
        """A first step [s] from the size of the state and of its derivatives (Hairer, Norsett and Wanner,
        Solving ODEs I, II.4), at most the output step."""
        model, control = self.system.model, self.control
        state = np.concatenate((model.magnitude(q), np.abs(v)))
        scale = control.atol + control.rtol * state
        derivative = np.concatenate((v, a))
        size, rate = _rms(state / scale), _rms(derivative / scale)
        first = 1e-6 if size < 1e-5 or rate < 1e-5 else 0.01 * size / rate
        q1, v1 = model.integrate(q, first * v), v + first * a
        a1 = self.system.acceleration(q1, v1, t + first, 0)
        curvature = _rms((np.concatenate((v1, a1)) - derivative) / scale) / first
        largest = max(rate, curvature)
        if largest <= 1e-15:
            second = max(1e-6, first * 1e-3)
        else:
            second = (0.01 / largest) ** (1.0 / (self.pair.tableau.order + 1))
        return min(100 * first, second, self.grid.duration)

    def _sample_grid(self, segment: Segment, q_end: np.ndarray, v_end: np.ndarray) -> None:
        """Keep the grid samples in (t0, t1] of an accepted step: its end state where a grid time falls on
        it, the dense output elsewhere."""
        grid = self.grid
        first = math.floor(segment.t0 / grid.dt + GRID_SLACK) + 1
        last = self.grid_index(segment.t1)
        for k in range(first, last + 1):
            time = grid.time(k)
            if abs(time - segment.t1) <= GRID_SLACK * grid.dt:
                self.keep(k, q_end, v_end)
            elif time < segment.t1:
                self.keep(k, *segment.state(time))


def _rms(values: np.ndarray) -> float:
    return float(np.linalg.norm(values)) / math.sqrt(len(values)) if len(values) else 0.0
