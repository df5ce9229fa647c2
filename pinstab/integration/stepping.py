"""The stepping loop of :func:`~pinstab.simulate.simulate`: steps in chunks, samples kept every K steps,
and checks between chunks.

The runs of steps between the passage watch's samples are the compiled loop's (:mod:`.compiled`: in C++, on every path,
with the path's compiled evaluation or the system's own called back); the Python step takes the others (the last,
shortened step, a passage's, a step of a method that corrects the state off the core path, an integrator of its own, a
step the compiled evaluation or correction leaves). Per step the loop calls the integrator (and the stabilizer's
correction, for methods that have one) and stores (q, v) on recorded steps; nothing else. Every :data:`CHECK_STEPS`
steps it checks the state: finite, drift below the limit, the native solve still accurate (``system.audit``), and for
state-dependent gains the spectral radius. When a check fails, the chunk is replayed from its start with a check after
every step, so a divergence is reported at the step where it happened, with the last good state, exactly as if every
step had been checked.
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

from ..constraints.joint_limits import LimitWatch
from ..errors import (
    ContactInfeasibleError,
    DivergenceError,
    NewtonError,
    PinstabError,
    ProjectionError,
    ServoInfeasibleError,
    SolverError,
    StepTooLargeError,
    StiffStepError,
    UnstableGainsWarning,
)
from ..projection import project_positions
from ..stability.criterion import mode_step_limit
from ..stability.modes import StiffMode, stiffest_mode
from ..stabilizers import ProjectionOptions
from ..system import ConstrainedSystem
from .compiled import CompiledSteps, steps_before
from .dense import Segment
from .passages import PassageWatch, Plan
from .records import Records
from .schemes import Integrator
from .stiffness import StiffWatch, stiff_reason, watched

CHECK_STEPS = 100  # steps between the loop's checks of the state (a check costs about two steps)
MAX_STEPS = 10**10  # beyond this a run takes days whatever the scene
MAX_SAMPLES = 20_000_000  # kept samples; beyond this the arrays alone reach gigabytes
MIN_DT = 1e-12  # [s]; below it t + dt rounds to t after a few hours of simulated time
PASSAGE_PROJECTION = ProjectionOptions()  # before a singular passage: the projection method's defaults
PROBE_STEPS = 10  # steps of dt past a failed step that a run with a smaller step must get through ...
PROBE_DIVISORS = (2, 4)  # ... with dt over these, for the failure to be the step's (StepTooLargeError)
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

    def times(self, steps: np.ndarray) -> np.ndarray:
        """:meth:`time` of each grid step in ``steps`` [s]."""
        return np.where(steps == self.steps, self.duration, steps * self.dt)


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
        corrects: the method corrects the state after each step.
        compiled: the compiled loop taking runs of steps (:mod:`pinstab.integration.compiled`), or None.
        limit_watch: fed every grid step's state (kept or not), or None: the joint limits a run that does not hold
            them watches (:class:`~pinstab.constraints.joint_limits.LimitWatch`).
        stiff_watch: the stiff-mode watch at the checks (:mod:`.stiffness`), or None (no force element, an implicit
            scheme or one the criterion does not know).
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
        self.corrects = system.stabilizer.corrects
        self.compiled = CompiledSteps.of(system, stepper)
        self.limit_watch: LimitWatch | None = None
        self.stiff_watch = StiffWatch.of(system, stepper, grid.dt, CHECK_STEPS)

    def watch_limits(self, watch: LimitWatch) -> None:
        """Feed ``watch`` every grid step's state from the start (times on this loop's grid)."""
        watch.time = self.grid.time
        self.limit_watch = watch

    def run(self, q: np.ndarray, v: np.ndarray, progress=None) -> tuple[np.ndarray, np.ndarray]:
        """Step from (q, v) at t = 0 to the end of the grid; returns the end state.

        Raises:
            DivergenceError: a check failed, or a solve failed on a state reached inside a step; at the
                step where it first fails, with the last good state, :attr:`records` ending with it.
            KeyboardInterrupt: Ctrl-C; :attr:`records` end with the last checked state.
            ContactInfeasibleError, ServoInfeasibleError: contacts that cannot hold, servos the controls cannot
                realize; :attr:`records` end with the last state that passed its checks.
            MemoryError: an allocation failed; :attr:`records` end with the last checked state.
        """
        self.records.put(0, q, v)
        self.start = (q, v)  # what a failure linearizes the motion at first (name_stiff_mode)
        if self.limit_watch is not None:
            self.limit_watch.see(0, q)
        self.watch = PassageWatch(
            self.system.model,
            q,
            self.stepper.nodes,
            self.grid.dt,
            self.system.conditioning,
            self.system.constraint_jacobian,
        )
        k = 0
        try:
            self.system.audit(q, v, 0.0)
            while k < self.grid.steps:
                q, v, k = self.chunk(q, v, k, progress)
        except (KeyboardInterrupt, ContactInfeasibleError, ServoInfeasibleError, MemoryError):
            if not self.records.ended:  # a replay that located the failure ended them at its step
                self.records.end_with((k, self.grid.time(k), q, v))
            raise
        return q, v

    def chunk(self, q: np.ndarray, v: np.ndarray, k: int, progress=None) -> tuple[np.ndarray, np.ndarray, int]:
        """Steps k+1 .. k + CHECK_STEPS (or to the end; a step further when a singular passage straddles the
        chunk's end) from the checked state (q, v) at step k, then a check; returns the state and its step.
        On a failure the chunk is replayed step by step."""
        stop = min(k + CHECK_STEPS, self.grid.steps)
        self.checked_state = (k, q, v)  # what a failure in the chunk linearizes the motion at (name_stiff_mode)
        counts = (self.correction_total, self.correction_max)
        saved = self.snapshot()
        try:
            q_end, v_end, reached = self.advance(q, v, k, stop)
            self.check(q_end, v_end, reached)
        except (Failure, DivergenceError, SolverError, ProjectionError) as exc:
            self.correction_total, self.correction_max = counts  # the replay counts its steps again
            self.restore(saved)
            replayed = self.locate(q, v, k, stop)
            # the replay passed every check (a warm-started solver took another path): report the chunk
            reason = f"{exc} (a replay checked after every step passed)"
            raise self.diverged(k, replayed, reason, q, v) from None
        if self.stiff_watch is not None:
            self.watch_stiffness(k, q, v, (reached, q_end, v_end))
        if progress is not None:
            progress.update(reached - k)
        self.records.checked(reached)
        return q_end, v_end, reached

    def watch_stiffness(
        self, good: int, q: np.ndarray, v: np.ndarray, checked: tuple[int, np.ndarray, np.ndarray]
    ) -> None:
        """Raise :class:`StiffStepError` when the stiff-mode watch stops the run at the check of ``checked`` (step,
        q, v), the chunk stepped from (q, v) at step ``good``: the records end with both."""
        t = self.grid.time(checked[0])
        seen = self.stiff_watch.see(checked[1], checked[2], t)
        if seen is None:
            return
        mode, limit, radius, growth = seen
        reason = (
            f"{stiff_reason(self.stepper.name, self.grid.dt, mode, limit, t)}. The mode grows by |R| = {radius:.4g} "
            f"per step there, {growth:.3g}-fold over the crossing ({CHECK_STEPS} steps a check): the steps ahead would "
            "give a wrong motion or none"
        )
        raise self.stiff_error(mode, limit, good, checked, reason, q, v)

    def stiff_error(
        self,
        mode: StiffMode,
        limit: float,
        good: int,
        failed: tuple[int, np.ndarray, np.ndarray],
        reason: str,
        q: np.ndarray,
        v: np.ndarray,
    ) -> StiffStepError:
        """The :class:`StiffStepError` of a run stopped for ``mode`` (its step ``limit`` [s]); see :meth:`diverged`."""
        error = self.diverged(good, failed, reason, q, v, StiffStepError)
        error.element, error.frequency, error.eigenvalue, error.limit = (
            mode.element,
            mode.frequency,
            mode.eigenvalue,
            limit,
        )
        return error

    def snapshot(self) -> tuple:
        """What a replayed chunk starts from besides the state (the passage watch's samples)."""
        return self.watch.snapshot()

    def restore(self, state: tuple) -> None:
        """Return to a :meth:`snapshot`."""
        self.watch.restore(state)

    def advance(self, q: np.ndarray, v: np.ndarray, start: int, stop: int) -> tuple[np.ndarray, np.ndarray, int]:
        """Steps start+1 .. stop from (q, v) at step ``start``, storing the recorded ones; returns the state
        and its step (beyond ``stop`` when the steps planned around a singular passage end there)."""
        step = self.stepper.step
        grid, watch = self.grid, self.watch
        dt, last = grid.dt, grid.steps
        corrects, keep, compiled = self.corrects, self.keep, self.compiled
        k = start
        while k < stop:
            t = k * dt
            if t >= watch.next_due:
                watch.sample(t, q)
                plan = watch.plan(t, dt, self.next_grid)
                if plan is not None:
                    q, v, k = self.passage(q, v, k, plan)
                    continue
            # the steps before the watch's next sample, the last grid step (shortened) excepted
            span = 0 if compiled is None else steps_before(k, min(stop, last - 1), dt, watch.next_due)
            if span:
                qs, vs, done, raised, iterations = compiled.run(q, v, k, dt, span)
                if done:
                    if iterations is not None:  # the method's corrections, made in the compiled loop
                        self.correction_total += int(iterations.sum())
                        self.correction_max = max(self.correction_max, int(iterations.max()))
                    self.records.put_span(k + 1, qs[:done], vs[:done], iterations)
                    if self.limit_watch is not None:
                        self.limit_watch.see_span(k + 1, qs[:done])
                    q, v, k = qs[done - 1], vs[done - 1], k + done
                if raised is not None:
                    raise raised
                if done == span:
                    continue
                t = k * dt  # the next step's evaluation is not to be used: the Python step takes it
            k += 1
            q, v = step(q, v, t, dt if k != last else grid.duration - t)
            if corrects:
                q, v = self.store(q, v, k)
            else:  # what store() does without a correction, a call less per step
                keep(k, q, v)
        return q, v, k

    def newton_figures(self) -> dict[str, int] | None:
        """What an implicit integrator's Newton iteration did so far (:func:`~pinstab.integration.implicit.
        newton_figures`), None for an explicit one."""
        return self.stepper.newton_figures()

    def store(self, q: np.ndarray, v: np.ndarray, k: int, t: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Correct the state reached at grid step k (at time t [s] when it is not a grid time: a step of a
        plan around a singular passage), count the correction and keep the sample when k is recorded."""
        iterations = 0
        stabilizer = self.system.stabilizer
        if stabilizer.corrects:
            correction = stabilizer.correct(
                self.system.model, self.system.projector, q, v, self.grid.time(k) if t is None else t
            )
            q, v, iterations = correction.q, correction.v, correction.iterations
            self.correction_total += iterations
            self.correction_max = max(self.correction_max, iterations)
        if t is None:
            self.keep(k, q, v, iterations)
        return q, v

    def keep(self, k: int, q: np.ndarray, v: np.ndarray, iterations: int = 0) -> None:
        """Store the sample of grid step k when it is a recorded one (the limit watch sees every one)."""
        if self.limit_watch is not None:
            self.limit_watch.see(k, q)
        if k % self.every == 0 or k == self.grid.steps:
            records = self.records
            records.put(records.index(k), q, v, iterations)

    @property
    def guarded(self) -> bool:
        """Whether the state is projected onto its branch before a singular passage (methods that do not
        correct every step, but ``none``)."""
        stabilizer = self.system.stabilizer
        return stabilizer.guards_passages and not stabilizer.corrects

    def project(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) projected onto the constraint manifold at t [s] (Gauss-Newton with the projection method's
        default settings, then the velocities)."""
        system = self.system
        settings = PASSAGE_PROJECTION
        q, _ = project_positions(system.model, system.projector, q, t, settings.tolerance, settings.max_iterations)
        return q, system.projector.velocity_projection(q, v, t)

    def grid_index(self, t: float) -> int:
        """The first grid step at or after time t [s] (the last step at most)."""
        grid = self.grid
        return min(math.ceil(t / grid.dt - GRID_SLACK), grid.steps)

    def grid_between(self, t0: float, t1: float) -> range:
        """The grid steps whose times lie in (t0, t1] [s] (with a sliver of a step of slack)."""
        grid = self.grid
        first = math.floor(t0 / grid.dt + GRID_SLACK) + 1
        last = (
            grid.steps
            if t1 >= grid.duration - GRID_SLACK * grid.dt
            else min(math.floor(t1 / grid.dt + GRID_SLACK), grid.steps)
        )
        return range(first, last + 1)

    def next_grid(self, t: float) -> float:
        """The first grid time at or after t [s] (the duration at most)."""
        return self.grid.time(self.grid_index(t))

    def passage(self, q: np.ndarray, v: np.ndarray, k: int, plan: Plan) -> tuple[np.ndarray, np.ndarray, int]:
        """The steps planned around a singular passage, from (q, v) at grid step k; a grid time inside the
        straddling step is sampled from its dense output. Returns the state and its grid step."""
        system, grid = self.system, self.grid
        t = grid.time(k)
        for index, end in enumerate(plan.ends):
            if index == plan.straddle:
                if self.guarded:
                    q, v = self.project(q, v, t)
                start = (t, q, v, system.acceleration(q, v, t, 0))
            q, v = self.stepper.step(q, v, t, end - t)
            on_grid = index == len(plan.ends) - 1
            q, v = self.store(q, v, self.grid_index(end), None if on_grid else end)
            if index == plan.straddle:
                segment = Segment(system.model, *start, end, q, v, system.acceleration(q, v, end, 0))
                for inside in range(self.grid_index(start[0] + GRID_SLACK * grid.dt), self.grid_index(end)):
                    if start[0] < grid.time(inside) < end:
                        self.keep(inside, *segment.state(grid.time(inside)))
                self.watch.locate(segment, start[1], q)
            t = end
        return q, v, self.grid_index(plan.ends[-1])

    def check(self, q: np.ndarray, v: np.ndarray, k: int) -> None:
        """Check the state after step k.

        Raises:
            Failure: non-finite, or drift above the limit.
        """
        system, grid = self.system, self.grid
        t = grid.time(k)
        self.check_state(q, v, t, t - grid.time(k - 1))
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

    def check_state(self, q: np.ndarray, v: np.ndarray, t: float, step: float) -> None:
        """Check the state reached at t [s] by a step of ``step`` [s].

        Raises:
            Failure: non-finite, or drift above the limit (the velocity residual times the step).
        """
        if not math.isfinite(q @ q + v @ v):
            raise Failure("a non-finite state")
        position, velocity = self.system.violation(q, v, t)
        drift = max(position, velocity * step)
        if not drift <= self.drift_limit:
            if not math.isfinite(drift):
                raise Failure("a non-finite state")
            raise Failure(f"drift {drift:.3g} > {self.drift_limit:g} (position residual, or velocity residual x dt)")

    def locate(self, q: np.ndarray, v: np.ndarray, start: int, stop: int) -> tuple[int, np.ndarray, np.ndarray]:
        """Replay steps start+1 .. stop from (q, v) with a check after each, and raise DivergenceError at
        the first that fails (a failed solve too, when it is a blow-up: see :meth:`solve_failure`);
        returns the step reached (``stop``, or beyond it after a singular passage) and its state when none
        fails."""
        k = start
        while k < stop:
            failed = (k + 1, np.full_like(q, np.nan), np.full_like(v, np.nan))
            cause: NewtonError | None = None
            try:
                q_next, v_next, reached = self.advance(q, v, k, k + 1)
                failed = (reached, q_next, v_next)
                self.check(q_next, v_next, reached)
            except Failure as exc:
                reason = str(exc)
            except NewtonError as exc:
                reason, cause = str(exc), exc
            except DivergenceError:
                reason = "a non-finite state"
            except ProjectionError as exc:
                reason = f"the post-step projection failed ({exc})"
            except SolverError as exc:
                self.name_step_size(k, failed, str(exc), q, v)
                self.records.end_with((k, self.grid.time(k), q, v))  # kept when the failure is not a blow-up
                reason = self.solve_failure(exc, q, v, self.grid.time(k))
            else:
                q, v, k = q_next, v_next, reached
                continue
            self.name_step_size(k, failed, reason, q, v, cause)
            raise self.diverged(k, failed, reason, q, v) from cause
        return k, q, v

    def name_step_size(
        self,
        good: int,
        failed: tuple[int, np.ndarray, np.ndarray],
        cause: str,
        q: np.ndarray,
        v: np.ndarray,
        newton: NewtonError | None = None,
    ) -> None:
        """Raise :class:`StepTooLargeError` when the step from (q, v) at grid step ``good`` failed (``cause``)
        only because dt is too large: the motion goes on with dt / 2 (or dt / 4) for :data:`PROBE_STEPS` steps
        of dt past that point. A failure of an implicit stage's Newton iteration (``newton``) is its ``__cause__``."""
        self.name_stiff_mode(good, failed, q, v)
        grid = self.grid
        t = grid.time(good)
        span = min(PROBE_STEPS * grid.dt, grid.duration - t)
        for divisor in PROBE_DIVISORS:
            if self.probe(q, v, t, span, grid.dt / divisor):
                suggested = grid.dt / divisor
                reason = (
                    f"dt = {grid.dt:g} s is too large for this motion: with it the step from t = {t:.6g} s fails "
                    f"({cause}), with dt = {suggested:g} s the motion goes on past t = {t + span:.6g} s; use "
                    f"--dt {suggested:g} or smaller (or --rtol, error control)"
                )
                raise self.diverged(good, failed, reason, q, v, StepTooLargeError) from newton

    def name_stiff_mode(
        self, good: int, failed: tuple[int, np.ndarray, np.ndarray], q: np.ndarray, v: np.ndarray
    ) -> None:
        """Raise :class:`StiffStepError` when dt is above the scheme's stability limit of the stiffest mode of the
        motion, a decaying mode a force element owns (:func:`~pinstab.stability.modes.stiffest_mode`), at the run's
        start or else at the last checked state before the failure (states the motion had, unlike the blown-up last
        finite one); the run failed from (q, v) at grid step ``good``."""
        scheme, dt = self.stepper.name, self.grid.dt
        if not watched(self.stepper, self.system.model):  # no known region, or no element
            return
        checked, checked_q, checked_v = self.checked_state
        states = [(0.0, *self.start)] + ([(self.grid.time(checked), checked_q, checked_v)] if checked else [])
        for t, at_q, at_v in states:
            mode = stiffest_mode(self.system.model, at_q, at_v, t)
            if mode is None or mode.element is None or not mode.eigenvalue.real < 0:
                continue
            limit = mode_step_limit(mode.eigenvalue, scheme)
            if dt > limit:
                break
        else:
            return
        raise self.stiff_error(mode, limit, good, failed, stiff_reason(scheme, dt, mode, limit, t), q, v)

    def probe(self, q: np.ndarray, v: np.ndarray, t: float, span: float, step: float) -> bool:
        """Whether steps of ``step`` [s] from (q, v) at t [s] get through ``span`` [s] with every solve and
        check passing (the run's records and counters untouched)."""
        counts = (self.correction_total, self.correction_max)
        end = t + span
        try:
            while t < end - GRID_SLACK * step:
                h = min(step, end - t)
                q, v = self.stepper.step(q, v, t, h)
                q, v = self.store(q, v, 0, t + h)
                t += h
                self.check_state(q, v, t, h)
        except (Failure, DivergenceError, SolverError, ProjectionError):
            return False
        finally:
            self.correction_total, self.correction_max = counts
        return True

    def solve_failure(self, exc: SolverError, q: np.ndarray, v: np.ndarray, t: float) -> str:
        """Why a solve that failed during the step from the good state (q, v) at t [s] is a blow-up: the
        gains were reported unstable, or the solver still solves (q, v) itself, so it failed on a state
        the step reached (a non-finite or exploding stage), or it fails on (q, v) too, a state the run reached
        after its start. Re-raises ``exc`` when it is neither: a contact that cannot hold, or a solver that fails
        on the start (the scene or the solver, not the run)."""
        if not self.warned:
            if isinstance(exc, ContactInfeasibleError):
                raise exc
            try:
                self.system.dynamics(q, v, t)
            except SolverError:
                if t == self.grid.time(0):  # the start state: the scene, not the run (bad input)
                    raise exc from None
                return f"the KKT solve failed at a state the run reached ({exc})"
        return f"a non-finite or exploding state (the KKT solve failed: {exc})"

    def diverged(
        self,
        good: int,
        failed: tuple[int, np.ndarray, np.ndarray],
        reason: str,
        q: np.ndarray,
        v: np.ndarray,
        error: type[DivergenceError] = DivergenceError,
    ) -> DivergenceError:
        """The error of a run whose step ``failed[0]`` failed (``reason``) with the state ``failed[1:]`` (NaN
        when not reached); the records end with the last good state (q, v), at step ``good``, then that one."""
        grid = self.grid
        t, t_failed = grid.time(good), grid.time(failed[0])
        self.records.end_with((good, t, q, v), (failed[0], t_failed, *failed[1:]))
        if issubclass(error, StepTooLargeError):
            message = f"the run stopped at t = {t_failed:.6g} s (step {failed[0]}): {reason}"
        else:
            message = (
                f"simulation diverged at t = {t_failed:.6g} s (step {failed[0]}): {reason}; the last finite state "
                f"is at t = {t:.6g} s. Reduce dt, change the gains, or use another method."
            )
        return error(message, t, q, v, diverged_at=t_failed)
