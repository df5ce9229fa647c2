"""The stepping loop of :func:`~pinstab.simulate.simulate`: steps in chunks, samples kept every K steps,
and checks between chunks.

Per step the loop calls the integrator (and the stabilizer's correction, for methods that have one)
and stores (q, v) on recorded steps; nothing else. Every :data:`CHECK_STEPS` steps it checks the
state: finite, drift below the limit, the native solve still accurate (``system.audit``), and for
state-dependent gains the spectral radius. When a check fails, the chunk is replayed from its start
with a check after every step, so a divergence is reported at the step where it happened, with the
last good state, exactly as if every step had been checked.
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

from ..errors import (
    ContactInfeasibleError,
    DivergenceError,
    PinstabError,
    ProjectionError,
    SolverError,
    UnstableGainsWarning,
)
from ..system import ConstrainedSystem
from .schemes import Integrator

CHECK_STEPS = 100  # steps between the loop's checks of the state (a check costs about two steps)
MAX_STEPS = 10**10  # beyond this a run takes days whatever the scene
MAX_SAMPLES = 20_000_000  # kept samples; beyond this the arrays alone reach gigabytes
MIN_DT = 1e-12  # [s]; below it t + dt rounds to t after a few hours of simulated time
GRID_SLACK = 1e-9  # a duration within this fraction of a step of a whole number of steps is that number


class TimeGrid(NamedTuple):
    """The steps of a run: ``steps`` steps of ``dt`` [s], the last shortened so that it ends at
    ``duration`` [s] exactly."""

    dt: float
    duration: float
    steps: int

    @classmethod
    def of(cls, dt: float, duration: float, every: int = 1) -> TimeGrid:
        """The grid of ``dt`` over ``duration`` (a dt longer than the duration is one step of the duration),
        keeping a sample every ``every`` steps.

        Raises:
            PinstabError: non-positive or non-finite arguments, dt below :data:`MIN_DT`, more than
                :data:`MAX_STEPS` steps or more than :data:`MAX_SAMPLES` kept samples.
        """
        for label, value in (("dt", dt), ("duration", duration)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
                raise PinstabError(f"{label} must be a positive number, got {value!r}")
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise PinstabError(f"record_every must be a whole number >= 1, got {every!r}")
        if dt < MIN_DT:
            raise PinstabError(f"dt = {dt:g} s is below {MIN_DT:g} s, where the time t + dt stops advancing")
        dt = min(dt, duration)  # one step of the whole duration
        ratio = duration / dt
        if ratio > MAX_STEPS:
            raise PinstabError(f"{ratio:.3g} steps (duration {duration:g} s / dt {dt:g} s) exceed {MAX_STEPS:.0e}")
        whole = round(ratio)
        steps = whole if abs(ratio - whole) <= GRID_SLACK * max(1.0, ratio) else math.ceil(ratio)
        steps = max(steps, 1)
        if steps // every > MAX_SAMPLES:
            raise PinstabError(
                f"{steps // every + 1:,} samples ({steps:,} steps, one kept every {every}) exceed the "
                f"{MAX_SAMPLES:,} a trajectory holds; keep fewer (record_every = {math.ceil(steps / MAX_SAMPLES)} "
                "or more), or use a larger dt or a shorter duration"
            )
        return cls(float(dt), float(duration), steps)

    def time(self, k: int) -> float:
        """The time of sample k [s]: k dt, and ``duration`` exactly at the last."""
        return self.duration if k == self.steps else k * self.dt


class Records:
    """The samples a run keeps: steps 0, K, 2K, ... and the last, each with t [s], q, v and the
    correction iterations of that step; one spare slot for a stopped run (see :meth:`end_with`).

    Args:
        grid: the run's time grid. every: K. nq, nv: state dimensions.

    Attributes:
        last: the slot of the run's last step. count: the samples kept (fewer when the run stopped early).
    """

    def __init__(self, grid: TimeGrid, every: int, nq: int, nv: int) -> None:
        self.every = every
        steps = np.arange(0, grid.steps + 1, every, dtype=np.int64)
        if steps[-1] != grid.steps:
            steps = np.append(steps, grid.steps)
        size = len(steps)
        self.steps = np.append(steps, grid.steps)  # the spare slot
        self.t = self.steps * grid.dt
        self.t[size - 1 :] = grid.time(grid.steps)
        self.q = np.zeros((size + 1, nq))
        self.v = np.zeros((size + 1, nv))
        self.corrections = np.zeros(size + 1, dtype=int)
        self.last = size - 1
        self.count = size

    def end_with(self, *samples: tuple[int, float, np.ndarray, np.ndarray]) -> None:
        """Keep the samples before the first of ``samples`` (step, t [s], q, v) and end with these (a run
        stopped there: its last good state, then at most one more, the failed step's)."""
        index = min(int(np.searchsorted(self.steps[: self.last + 1], samples[0][0])), self.last)
        for slot, (step, t, q, v) in enumerate(samples, start=index):
            self.steps[slot], self.t[slot], self.q[slot], self.v[slot] = step, t, q, v
        self.count = index + len(samples)


class Failure(Exception):
    """A check found the state diverged (internal: turned into a DivergenceError at its step)."""


class StepLoop:
    """Steps a bound system over a time grid.

    Args:
        system: the system, bound to the step and the integrator.
        stepper: the integrator.
        grid: the time grid.
        every: keep a sample every this many steps (and the last).
        drift_limit: position drift [m or rad] (or velocity drift x dt) that counts as divergence.
        warned: the gains were already reported unstable (a failing solve is then the blow-up the
            criterion foresaw, not an error).

    Attributes:
        records: the kept samples. correction_total, correction_max: post-step correction iterations.
    """

    def __init__(
        self,
        system: ConstrainedSystem,
        stepper: Integrator,
        grid: TimeGrid,
        every: int,
        drift_limit: float,
        warned: bool,
    ) -> None:
        self.system = system
        self.stepper = stepper
        self.grid = grid
        self.every = every
        self.drift_limit = drift_limit
        self.warned = warned
        model = system.model
        self.records = Records(grid, every, model.nq, model.nv)
        self.correction_total = 0
        self.correction_max = 0

    def run(self, q: np.ndarray, v: np.ndarray, progress=None) -> tuple[np.ndarray, np.ndarray]:
        """Step from (q, v) at t = 0 to the end of the grid; returns the end state.

        Raises:
            DivergenceError: a check failed, or a solve failed on a state reached inside a step; at the
                step where it first fails, with the last good state, :attr:`records` ending with it.
            KeyboardInterrupt: Ctrl-C; :attr:`records` end with the last checked state.
        """
        self.records.q[0], self.records.v[0] = q, v
        self.system.audit(q, v, 0.0)
        k = 0
        try:
            while k < self.grid.steps:
                q, v, k = self.chunk(q, v, k, progress)
        except KeyboardInterrupt:
            self.records.end_with((k, self.grid.time(k), q, v))
            raise
        return q, v

    def chunk(self, q: np.ndarray, v: np.ndarray, k: int, progress=None) -> tuple[np.ndarray, np.ndarray, int]:
        """Steps k+1 .. k + CHECK_STEPS (or to the end) from the checked state (q, v) at step k, then a
        check; returns the state and its step. On a failure the chunk is replayed step by step."""
        stop = min(k + CHECK_STEPS, self.grid.steps)
        counts = (self.correction_total, self.correction_max)
        try:
            q_end, v_end = self.advance(q, v, k, stop)
            self.check(q_end, v_end, stop)
        except (Failure, DivergenceError, SolverError, ProjectionError) as exc:
            self.correction_total, self.correction_max = counts  # the replay counts its steps again
            replayed = self.locate(q, v, k, stop)
            # the replay passed every check (a warm-started solver took another path): report the chunk
            reason = f"{exc} (a replay checked after every step passed)"
            raise self.diverged(k, (stop, *replayed), reason, q, v) from None
        if progress is not None:
            progress.update(stop - k)
        return q_end, v_end, stop

    def advance(self, q: np.ndarray, v: np.ndarray, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Steps start+1 .. stop from (q, v) at step ``start``, storing the recorded ones."""
        step = self.stepper.step
        stabilizer = self.system.stabilizer
        correct = stabilizer.correct if stabilizer.corrects else None
        model, projector = self.system.model, self.system.projector
        grid = self.grid
        dt, last, every = grid.dt, grid.steps, self.every
        rq, rv, corrections = self.records.q, self.records.v, self.records.corrections
        for k in range(start + 1, stop + 1):
            t = (k - 1) * dt
            q, v = step(q, v, t, dt if k != last else grid.duration - t)
            iterations = 0
            if correct is not None:
                correction = correct(model, projector, q, v, grid.time(k))
                q, v, iterations = correction.q, correction.v, correction.iterations
                self.correction_total += iterations
                self.correction_max = max(self.correction_max, iterations)
            if k % every == 0 or k == last:
                index = self.records.last if k == last else k // every
                rq[index], rv[index], corrections[index] = q, v, iterations
        return q, v

    def check(self, q: np.ndarray, v: np.ndarray, k: int) -> None:
        """Check the state after step k.

        Raises:
            Failure: non-finite, or drift above the limit.
        """
        system, grid = self.system, self.grid
        t = grid.time(k)
        if not math.isfinite(q @ q + v @ v):
            raise Failure("a non-finite state")
        position, velocity = system.model.violation(q, v, t)
        drift = max(position, velocity * (t - grid.time(k - 1)))
        if not drift <= self.drift_limit:
            if not math.isfinite(drift):
                raise Failure("a non-finite state")
            raise Failure(f"drift {drift:.3g} > {self.drift_limit:g} (position residual, or velocity residual x dt)")
        system.audit(q, v, t)
        stabilizer = system.stabilizer
        if not stabilizer.constant_gains and not self.warned:
            radius = stabilizer.spectral_radius(system.model, q, v, t)
            if radius is not None and radius >= 1.0:
                self.warned = True
                warnings.warn(
                    UnstableGainsWarning(
                        f"at t = {t:.6g} s the deviation dynamics of method {stabilizer.name} reached "
                        f"rho(R(tau W)) = {radius:.4g} >= 1 (state-dependent gains): constraint errors may grow "
                        "from here"
                    ),
                    stacklevel=4,
                )

    def locate(self, q: np.ndarray, v: np.ndarray, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """Replay steps start+1 .. stop from (q, v) with a check after each, and raise DivergenceError at
        the first that fails (a failed solve too, when it is a blow-up: see :meth:`solve_failure`);
        returns the state at ``stop`` when none fails."""
        for k in range(start + 1, stop + 1):
            failed = np.full_like(q, np.nan), np.full_like(v, np.nan)
            try:
                q_next, v_next = self.advance(q, v, k - 1, k)
                failed = q_next, v_next
                self.check(q_next, v_next, k)
            except Failure as exc:
                reason = str(exc)
            except DivergenceError:
                reason = "a non-finite state"
            except ProjectionError as exc:
                reason = f"the post-step projection failed ({exc})"
            except SolverError as exc:
                reason = self.solve_failure(exc, q, v, self.grid.time(k - 1))
            else:
                q, v = q_next, v_next
                continue
            raise self.diverged(k - 1, (k, *failed), reason, q, v)
        return q, v

    def solve_failure(self, exc: SolverError, q: np.ndarray, v: np.ndarray, t: float) -> str:
        """Why a solve that failed during the step from the good state (q, v) at t [s] is a blow-up: the
        gains were reported unstable, or the solver still solves (q, v) itself, so it failed on a state
        the step reached (a non-finite or exploding stage). Re-raises ``exc`` when it is not: a contact
        that cannot hold, or a solver that fails on (q, v) too (the scene or the solver, not the step)."""
        if not self.warned:
            if isinstance(exc, ContactInfeasibleError):
                raise exc
            try:
                self.system.dynamics(q, v, t)
            except SolverError:
                raise exc from None
        return f"a non-finite or exploding state (the KKT solve failed: {exc})"

    def diverged(
        self, good: int, failed: tuple[int, np.ndarray, np.ndarray], reason: str, q: np.ndarray, v: np.ndarray
    ) -> DivergenceError:
        """The error of a run whose step ``failed[0]`` failed (``reason``) with the state ``failed[1:]`` (NaN
        when not reached); the records end with the last good state (q, v), at step ``good``, then that one."""
        grid = self.grid
        t, t_failed = grid.time(good), grid.time(failed[0])
        self.records.end_with((good, t, q, v), (failed[0], t_failed, *failed[1:]))
        return DivergenceError(
            f"simulation diverged at t = {t_failed:.6g} s (step {failed[0]}): {reason}; the last finite state "
            f"is at t = {t:.6g} s. Reduce dt, change the gains, or use another method.",
            t,
            q,
            v,
            diverged_at=t_failed,
        )
