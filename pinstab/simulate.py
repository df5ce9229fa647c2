"""``simulate()``: assemble, then step a scene with a stabilizer, an integrator and a KKT backend."""

from __future__ import annotations

import math
import sys
import time
import warnings
from collections.abc import Mapping
from contextlib import closing, nullcontext
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .assembly import AssemblyReport, assemble
from .errors import DivergenceError, PinstabError, SolverError, UnstableGainsError, UnstableGainsWarning
from .integrators import INTEGRATORS
from .runinfo import RunInfo
from .scene import Scene, load_scene
from .stability import largest_stable_step
from .system import ConstrainedSystem, build_system
from .trajectory import Trajectory

DEFAULT_DRIFT_LIMIT = 1.0  # [m or rad]: beyond this the run is declared diverged
MAX_STEPS = 20_000_000  # every step is recorded; beyond this the arrays alone reach gigabytes
GRID_SLACK = 1e-9  # a duration within this fraction of a step of a whole number of steps is that number


class TimeGrid(NamedTuple):
    """The steps of a run: ``steps`` steps of ``dt`` [s], the last shortened so that it ends at
    ``duration`` [s] exactly."""

    dt: float
    duration: float
    steps: int

    @classmethod
    def of(cls, dt: float, duration: float) -> TimeGrid:
        """The grid of ``dt`` over ``duration``.

        Raises:
            PinstabError: non-positive or non-finite arguments, or more than :data:`MAX_STEPS` steps.
        """
        for label, value in (("dt", dt), ("duration", duration)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
                raise PinstabError(f"{label} must be a positive number, got {value!r}")
        ratio = duration / dt
        whole = round(ratio)
        steps = whole if abs(ratio - whole) <= GRID_SLACK * max(1.0, ratio) else math.ceil(ratio)
        steps = max(steps, 1)
        if steps > MAX_STEPS:
            raise PinstabError(
                f"{steps:,} steps (duration {duration} s / dt {dt} s) exceed the {MAX_STEPS:,} a trajectory records; "
                "use a larger dt or a shorter duration"
            )
        return cls(float(dt), float(duration), steps)

    def time(self, k: int) -> float:
        """The time of sample k [s]: k dt, and ``duration`` exactly at the last."""
        return self.duration if k == self.steps else k * self.dt


def simulate(
    scene: Scene | str | Path,
    method: str = "baumgarte",
    integrator: str = "rk4",
    dt: float = 1e-3,
    duration: float = 1.0,
    solver: str | None = None,
    *,
    solver_options: Mapping[str, Any] | None = None,
    strict: bool = False,
    drift_limit: float = DEFAULT_DRIFT_LIMIT,
    progress: bool = False,
    q0: np.ndarray | None = None,
    v0: np.ndarray | None = None,
    assemble_initial: bool = True,
    **method_options: Any,
) -> Trajectory:
    """Simulate a scene.

    Args:
        scene: a :class:`Scene`, a scene file path or a bundled scene name.
        method: a registered stabilization method (``none``, ``baumgarte``, ``mukharlyamov``,
            ``projection``, ``post``, ``pinocchio``, or one registered by the user).
        integrator: a registered integrator (``euler``, ``semi-implicit-euler``, ``heun``, ``rk4``).
        dt: time step [s]; the last step is shortened so that the run ends at ``duration`` exactly.
        duration: simulated time [s].
        solver: a registered KKT backend (``proxsuite`` by default, ``pinocchio``, ``dense``).
        solver_options: the backend's options (e.g. ``{"eps_abs": 1e-10}`` for proxsuite).
        method_options: the method's options, e.g. ``kp``, ``kd`` [1/s^2], [1/s] (``baumgarte``,
            ``pinocchio``; for ``mukharlyamov`` the stiffness and damping, omitted for automatic
            gains), ``variant``, ``decay``, ``hold`` (``mukharlyamov``). An option the method does not
            take is refused, naming the ones it takes.
        strict: refuse (:class:`UnstableGainsError`) instead of warning when the gains are
            predicted unstable (rho(R(tau W)) >= 1) at this step and integrator.
        drift_limit: position drift [m or rad] above which the run stops with DivergenceError; a
            velocity drift above ``drift_limit / dt`` stops it too.
        progress: show a progress bar on stderr for runs longer than a couple of seconds.
        q0, v0: initial state overriding the scene's.
        assemble_initial: make the initial state consistent first (off: start as given, e.g. to
            study how a method removes an initial violation).

    Returns:
        The :class:`Trajectory`.

    Raises:
        DivergenceError: non-finite state or drift above ``drift_limit``; carries the last finite
            state, its time and the partial trajectory.
        UnstableGainsError: with ``strict``, gains predicted unstable, before any step.

    Warns:
        UnstableGainsWarning: gains predicted unstable, before any step (without ``strict``).
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    grid = TimeGrid.of(dt, duration)
    if isinstance(drift_limit, bool) or not isinstance(drift_limit, int | float) or not drift_limit > 0:
        raise PinstabError(f"drift_limit must be a positive number, got {drift_limit!r}")
    system = build_system(scene, method, solver, solver_options, **method_options)
    stepper = INTEGRATORS.build(integrator, system)
    model = system.model
    q = scene.q0.copy() if q0 is None else np.asarray(q0, dtype=float).copy()
    v = scene.v0.copy() if v0 is None else np.asarray(v0, dtype=float).copy()
    if q.shape != (model.nq,) or v.shape != (model.nv,):
        raise PinstabError(f"q0 must have {model.nq} entries and v0 {model.nv}")
    report: AssemblyReport | None = None
    if assemble_initial:
        report = assemble(model, q, v)
        q, v = report.q, report.v
    system.stabilizer.bind(model, grid.dt, integrator, q)
    start_radius = _refuse_unstable_gains(system, q, v, strict)

    info = _info(scene, system, integrator, grid, report, method, solver_options)
    recorder = _Recorder(system, grid.steps)
    recorder.warned = start_radius is not None and start_radius >= 1.0
    recorder.record(0, 0.0, q, v)
    bar = _progress_bar(grid.steps, scene.name, progress)
    start = time.perf_counter()
    t = 0.0
    # a diverging run overflows before it is caught and reported; numpy's warnings would only add noise
    with np.errstate(over="ignore", invalid="ignore"), nullcontext() if bar is None else closing(bar):
        for k in range(1, grid.steps + 1):
            t_next = grid.time(k)
            step_size = t_next - t
            failure = ""
            try:
                step = stepper.step(q, v, t, step_size)
            except (DivergenceError, SolverError) as exc:
                if isinstance(exc, SolverError) and not recorder.warned:
                    raise
                # with gains predicted unstable, a solve that fails is the blow-up the criterion foresaw
                failure = f" (the KKT solve failed: {exc})" if isinstance(exc, SolverError) else ""
                recorder.record(k, t_next, np.full_like(q, np.nan), np.full_like(v, np.nan))
                drift = math.nan
            else:
                recorder.multipliers[k - 1] = step.start.multipliers
                correction = system.stabilizer.correct(model, step.q, step.v, t_next)
                recorder.corrections[k] = correction.iterations
                q_next, v_next = correction.q, correction.v
                drift = recorder.record(k, t_next, q_next, v_next)
                # a velocity residual that would carry the constraint past the limit within one step
                drift = max(drift, recorder.velocity_drift[k] * step_size)
            if not drift <= drift_limit:
                recorder.wall_time = time.perf_counter() - start
                partial = recorder.trajectory(k, _finish(info, system, k, t_next))
                reason = (
                    f"a non-finite state{failure}"
                    if not np.isfinite(drift)
                    else f"drift {drift:.3g} > {drift_limit:g} (position residual, or velocity residual x dt)"
                )
                raise DivergenceError(
                    f"simulation diverged at t = {t_next:.6g} s (step {k}): {reason}; the last finite state is at "
                    f"t = {t:.6g} s. Reduce dt, change the gains, or use another method.",
                    t,
                    q,
                    v,
                    partial,
                )
            q, v, t = q_next, v_next, t_next
            if bar is not None:
                bar.update(1)
        recorder.multipliers[grid.steps] = system.dynamics(q, v, t).multipliers
    recorder.wall_time = time.perf_counter() - start
    return recorder.trajectory(grid.steps, _finish(info, system, grid.steps, t))


class _Recorder:
    def __init__(self, system: ConstrainedSystem, steps: int) -> None:
        self.system = system
        self.model = system.model
        n = steps + 1
        self.t = np.zeros(n)
        self.q = np.zeros((n, self.model.nq))
        self.v = np.zeros((n, self.model.nv))
        self.multipliers = np.full((n, self.model.constraints.rows), np.nan)
        self.position_drift = np.zeros(n)
        self.velocity_drift = np.zeros(n)
        self.energy = np.zeros(n)
        self.corrections = np.zeros(n, dtype=int)
        self.spectral_radius = np.full(n, np.nan)
        self.warned = False  # one warning per run when rho first reaches 1 mid-run
        self.wall_time = 0.0

    def record(self, k: int, t: float, q: np.ndarray, v: np.ndarray) -> float:
        self.t[k], self.q[k], self.v[k] = t, q, v
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            self.position_drift[k] = self.velocity_drift[k] = self.energy[k] = np.nan
            return math.nan
        self.position_drift[k], self.velocity_drift[k] = self.model.violation(q, v, t)
        self.energy[k] = self.model.energy(q, v)
        radius = self.system.stabilizer.spectral_radius(self.model, q, v, t)
        if radius is not None:
            self.spectral_radius[k] = radius
            if radius >= 1.0 and not self.warned and k > 0:
                self.warned = True
                warnings.warn(
                    UnstableGainsWarning(
                        f"at t = {t:.6g} s the deviation dynamics of method {self.system.stabilizer.name} reached "
                        f"rho(R(tau W)) = {radius:.4g} >= 1 (state-dependent gains): constraint errors may grow "
                        "from here"
                    ),
                    stacklevel=4,
                )
        return float(self.position_drift[k])

    def trajectory(self, last: int, info: RunInfo) -> Trajectory:
        n = last + 1
        return Trajectory(
            t=self.t[:n].copy(),
            q=self.q[:n].copy(),
            v=self.v[:n].copy(),
            multipliers=self.multipliers[:n].copy(),
            position_drift=self.position_drift[:n].copy(),
            velocity_drift=self.velocity_drift[:n].copy(),
            energy=self.energy[:n].copy(),
            wall_time=self.wall_time,
            info=info,
            correction_iterations=self.corrections[:n].copy(),
            spectral_radius=self.spectral_radius[:n].copy(),
        )


def _info(
    scene: Scene,
    system: ConstrainedSystem,
    integrator: str,
    grid: TimeGrid,
    report: AssemblyReport | None,
    method: str,
    solver_options: Mapping[str, Any] | None,
) -> RunInfo:
    constraints = system.model.constraints
    return RunInfo(
        scene=scene.name,
        method=method,
        integrator=integrator,
        solver=system.solver.name,
        dt=grid.dt,
        parameters=system.stabilizer.parameters(),
        solver_options=dict(solver_options or {}),
        scene_parameters=scene.parameters,
        constraint_rows={name: [s.start, s.stop] for name, s in constraints.slices.items()},
        row_kinds={c.name: c.row_kind.value for c in constraints.constraints},
        force_frames={c.name: c.force_frame for c in constraints.constraints},
        assembly=None if report is None else report.summary(),
        direct=system.direct,
    )


def _finish(info: RunInfo, system: ConstrainedSystem, steps: int, t_end: float) -> RunInfo:
    """The run info with the steps taken, the end time [s] and the solver's statistics so far."""
    info.steps, info.t_end = steps, t_end
    info.solver_statistics = system.solver.statistics
    return info


def _refuse_unstable_gains(system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, strict: bool) -> float | None:
    """Warn (or refuse with ``strict``) before stepping when rho(R(tau W)) >= 1 at the start; returns rho."""
    stabilizer = system.stabilizer
    radius = stabilizer.spectral_radius(system.model, q, v, 0.0)
    if radius is None or radius < 1.0:
        return radius
    bound = largest_stable_step(*stabilizer.deviation_gains(system.model, q, v), stabilizer.scheme)
    step = stabilizer.step
    gains = stabilizer.parameters()
    described = ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}" for k, v in gains.items())
    scale = bound / step
    advice = f"stable for dt < {bound:.3g} s with these gains" if bound > 0 else "no step is stable with these gains"
    if "kp" in gains or "stiffness" in gains:
        kp = gains.get("kp", gains.get("stiffness"))
        kd = gains.get("kd", gains.get("damping"))
        advice += (
            f"; at dt = {step:g} s, gains below Kp = {kp * scale**2:.3g}, Kd = {kd * scale:.3g} (the same ratio) "
            "are stable"
        )
    message = (
        f"method {stabilizer.name} ({described}) with {stabilizer.integrator} at dt = {step:g} s: the deviation "
        f"dynamics have spectral radius rho(R(tau W)) = {radius:.4g} >= 1, so constraint errors grow instead of "
        f"decaying. {advice[0].upper() + advice[1:]}; or use --method mukharlyamov, whose automatic gains are "
        "placed for the step and the integrator."
    )
    if strict:
        raise UnstableGainsError(message)
    warnings.warn(UnstableGainsWarning(message), stacklevel=3)
    return radius


def _progress_bar(steps: int, label: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=steps, desc=label, unit="step", file=sys.stderr, delay=2.0, mininterval=0.5, leave=False)
