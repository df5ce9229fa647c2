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

from .errors import DivergenceError, PinstabError, SolverError, UnstableGainsWarning
from .integrators import Integrator
from .system import ConstrainedSystem

CHECK_STEPS = 100  # steps between the loop's checks of the state (a check costs about two steps)
MAX_STEPS = 10**10  # beyond this a run takes days whatever the scene
MAX_SAMPLES = 20_000_000  # kept samples; beyond this the arrays alone reach gigabytes
GRID_SLACK = 1e-9  # a duration within this fraction of a step of a whole number of steps is that number


class TimeGrid(NamedTuple):
    """The steps of a run: ``steps`` steps of ``dt`` [s], the last shortened so that it ends at
    ``duration`` [s] exactly."""

    dt: float
    duration: float
    steps: int

    @classmethod
    def of(cls, dt: float, duration: float, every: int = 1) -> TimeGrid:
        """The grid of ``dt`` over ``duration``, keeping a sample every ``every`` steps.

        Raises:
            PinstabError: non-positive or non-finite arguments, more than :data:`MAX_STEPS` steps or
                more than :data:`MAX_SAMPLES` kept samples.
        """
        for label, value in (("dt", dt), ("duration", duration)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
                raise PinstabError(f"{label} must be a positive number, got {value!r}")
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise PinstabError(f"record_every must be a whole number >= 1, got {every!r}")
        ratio = duration / dt
        whole = round(ratio)
        steps = whole if abs(ratio - whole) <= GRID_SLACK * max(1.0, ratio) else math.ceil(ratio)
        steps = max(steps, 1)
        if steps > MAX_STEPS:
            raise PinstabError(f"{steps:,} steps (duration {duration} s / dt {dt} s) exceed {MAX_STEPS:,}")
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
    correction iterations of that step.

    Args:
        grid: the run's time grid. every: K. nq, nv: state dimensions.
    """

    def __init__(self, grid: TimeGrid, every: int, nq: int, nv: int) -> None:
        self.every = every
        steps = np.arange(0, grid.steps + 1, every, dtype=np.int64)
        if steps[-1] != grid.steps:
            steps = np.append(steps, grid.steps)
        self.steps = steps
        self.t = steps * grid.dt
        self.t[-1] = grid.time(int(steps[-1]))
        size = len(steps)
        self.q = np.zeros((size, nq))
        self.v = np.zeros((size, nv))
        self.corrections = np.zeros(size, dtype=int)
        self.count = size  # samples of the run (fewer when it stopped early)

    def truncate_at(self, step: int, t: float, q: np.ndarray, v: np.ndarray) -> None:
        """Keep the samples before ``step`` and end with this state (a run stopped there)."""
        index = min(int(np.searchsorted(self.steps, step)), len(self.t) - 1)
        self.steps[index], self.t[index], self.q[index], self.v[index] = step, t, q, v
        self.count = index + 1


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
            DivergenceError: a check failed; at the step where it first fails, with the last good
                state and the partial trajectory's samples in :attr:`records`.
        """
        self.records.q[0], self.records.v[0] = q, v
        self.system.audit(q, v, 0.0)
        steps = self.grid.steps
        k = 0
        while k < steps:
            stop = min(k + CHECK_STEPS, steps)
            counts = (self.correction_total, self.correction_max)
            try:
                q_end, v_end = self.advance(q, v, k, stop)
                self.check(q_end, v_end, stop)
            except (Failure, DivergenceError, SolverError) as exc:
                self.correction_total, self.correction_max = counts  # the replay counts its steps again
                self.locate(q, v, k, stop)
                # the replay passed every check (a warm-started solver took another path): report the chunk
                if isinstance(exc, Failure):
                    raise DivergenceError(
                        f"simulation diverged by t = {self.grid.time(stop):.6g} s (step {stop}): {exc}; the last "
                        f"checked state is at t = {self.grid.time(k):.6g} s. Reduce dt, change the gains, or use "
                        "another method.",
                        self.grid.time(k),
                        q,
                        v,
                    ) from None
                raise
            if progress is not None:
                progress.update(stop - k)
            q, v, k = q_end, v_end, stop
        return q, v

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
                index = -1 if k == last else k // every
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

    def locate(self, q: np.ndarray, v: np.ndarray, start: int, stop: int) -> None:
        """Replay steps start+1 .. stop from (q, v) with a check after each, and raise DivergenceError at
        the first that fails (a solver error too, when the gains were reported unstable)."""
        grid = self.grid
        for k in range(start + 1, stop + 1):
            t, t_next = grid.time(k - 1), grid.time(k)
            try:
                q_next, v_next = self.advance(q, v, k - 1, k)
                self.check(q_next, v_next, k)
                q, v = q_next, v_next
                continue
            except SolverError as exc:
                if not self.warned:
                    raise
                # with gains predicted unstable, a solve that fails is the blow-up the criterion foresaw
                reason = f"a non-finite state (the KKT solve failed: {exc})"
                q_next, v_next = np.full_like(q, np.nan), np.full_like(v, np.nan)
            except DivergenceError:
                reason = "a non-finite state"
                q_next, v_next = np.full_like(q, np.nan), np.full_like(v, np.nan)
            except Failure as exc:
                reason = str(exc)
            self.records.truncate_at(k, t_next, q_next, v_next)
            raise DivergenceError(
                f"simulation diverged at t = {t_next:.6g} s (step {k}): {reason}; the last finite state "
                f"is at t = {t:.6g} s. Reduce dt, change the gains, or use another method.",
                t,
                q,
                v,
            )
