"""``simulate()``: assemble, then step a scene with a stabilizer, an integrator and a KKT backend."""

from __future__ import annotations

import math
import sys
import time
import warnings
from contextlib import closing, nullcontext
from pathlib import Path
from typing import Any

import numpy as np

from .assembly import AssemblyReport, assemble
from .errors import DivergenceError, PinstabError, UnstableGainsError, UnstableGainsWarning, choices
from .integrators import make_integrator
from .scene import Scene, load_scene
from .solvers import SOLVERS, DenseSolver, KKTSolver, PinocchioSolver, ProxsuiteSolver
from .stability import largest_stable_step
from .stabilizers import Stabilizer, make_stabilizer
from .system import ConstrainedSystem
from .trajectory import Trajectory

DEFAULT_DRIFT_LIMIT = 1.0  # [m or rad]: beyond this the run is declared diverged
MAX_STEPS = 20_000_000  # every step is recorded; beyond this the arrays alone reach gigabytes


def make_solver(name: str, scene: Scene, stabilizer: Stabilizer) -> KKTSolver:
    """KKT backend by name; ``pinocchio`` takes the stabilizer's Baumgarte gains into its corrector."""
    if stabilizer.required_solver is not None and name != stabilizer.required_solver:
        raise PinstabError(f"method {stabilizer.name!r} runs on solver {stabilizer.required_solver!r}, not {name!r}")
    if name == "proxsuite":
        return ProxsuiteSolver()
    if name == "dense":
        rows = scene.constraint_set
        return DenseSolver([c.name for c in rows.constraints for _ in range(c.rows)])
    if name == "pinocchio":
        gains = stabilizer.baumgarte_gains()
        if gains is None:
            raise PinstabError(
                f"solver 'pinocchio' cannot apply the stabilization term of method {stabilizer.name!r} "
                "(Pinocchio only applies its own Baumgarte corrector); use solver 'proxsuite' or 'dense'"
            )
        return PinocchioSolver(scene.model, scene.constraints, *gains)
    raise PinstabError(f"unknown solver {name!r}; valid solvers: {choices(SOLVERS)}")


def build_system(
    scene: Scene,
    method: str,
    solver: str | None,
    kp: float | None = None,
    kd: float | None = None,
    variant: str | None = None,
    decay: float | None = None,
    hold: bool | None = None,
) -> ConstrainedSystem:
    """A :class:`ConstrainedSystem` for the named method and solver (solver None: the method's own or proxsuite).

    Methods with step-dependent gains (``mukharlyamov``) need ``system.stabilizer.bind(...)`` before
    ``system.dynamics``; :func:`simulate` does it.
    """
    stabilizer = make_stabilizer(method, kp, kd, variant, decay, hold)
    solver_name = solver or stabilizer.required_solver or "proxsuite"
    return ConstrainedSystem(scene, stabilizer, make_solver(solver_name, scene, stabilizer))


def simulate(
    scene: Scene | str | Path,
    method: str = "baumgarte",
    integrator: str = "rk4",
    dt: float = 1e-3,
    duration: float = 1.0,
    solver: str | None = None,
    kp: float | None = None,
    kd: float | None = None,
    variant: str | None = None,
    decay: float | None = None,
    hold: bool | None = None,
    strict: bool = False,
    drift_limit: float = DEFAULT_DRIFT_LIMIT,
    progress: bool = False,
    q0: np.ndarray | None = None,
    v0: np.ndarray | None = None,
    assemble_initial: bool = True,
) -> Trajectory:
    """Simulate a scene.

    Args:
        scene: a :class:`Scene`, a scene file path or a bundled scene name.
        method: stabilization method (``none``, ``baumgarte``, ``projection``, ``post``, ``pinocchio``).
        integrator: ``euler``, ``semi-implicit-euler``, ``heun`` or ``rk4``.
        dt: time step [s].
        duration: simulated time [s].
        solver: ``proxsuite`` (default), ``pinocchio`` or ``dense``.
        kp, kd: Baumgarte gains [1/s^2], [1/s] (``baumgarte``, ``pinocchio``), or the stiffness
            and damping of ``mukharlyamov`` (omit both for automatic gains).
        variant: ``mukharlyamov``: ``kinematic`` (default) or ``inertial``.
        decay: ``mukharlyamov`` automatic gains: decay factor r per step (default 0 kinematic, 0.3 inertial).
        hold: ``mukharlyamov`` with heun or rk4: evaluate the term once per step and hold it
            (default True) rather than at every stage.
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
    for label, value in (("dt", dt), ("duration", duration), ("drift_limit", drift_limit)):
        if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
            raise PinstabError(f"{label} must be a positive number, got {value!r}")
    steps = int(round(duration / dt))
    if steps < 1:
        raise PinstabError(f"duration {duration} s is shorter than one step of dt = {dt} s")
    if steps > MAX_STEPS:
        raise PinstabError(
            f"{steps:,} steps (duration {duration} s / dt {dt} s) exceed the {MAX_STEPS:,} a trajectory records; "
            "use a larger dt or a shorter duration"
        )
    system = build_system(scene, method, solver, kp, kd, variant, decay, hold)
    stepper = make_integrator(integrator, system)
    q = scene.q0.copy() if q0 is None else np.asarray(q0, dtype=float).copy()
    v = scene.v0.copy() if v0 is None else np.asarray(v0, dtype=float).copy()
    if q.shape != (scene.model.nq,) or v.shape != (scene.model.nv,):
        raise PinstabError(f"q0 must have {scene.model.nq} entries and v0 {scene.model.nv}")
    report: AssemblyReport | None = None
    if assemble_initial:
        report = assemble(system, q, v)
        q, v = report.q, report.v
    system.stabilizer.bind(system, dt, integrator, q)
    start_radius = _refuse_unstable_gains(system, q, v, strict)

    recorder = _Recorder(system, steps)
    recorder.warned = start_radius is not None and start_radius >= 1.0
    recorder.record(0, 0.0, q, v)
    bar = _progress_bar(steps, scene.name, progress)
    start = time.perf_counter()
    t = 0.0
    # a diverging run overflows before it is caught and reported; numpy's warnings would only add noise
    with np.errstate(over="ignore", invalid="ignore"), nullcontext() if bar is None else closing(bar):
        for k in range(1, steps + 1):
            try:
                step = stepper.step(q, v, t, dt)
            except DivergenceError:
                recorder.record(k, k * dt, np.full_like(q, np.nan), np.full_like(v, np.nan))
                drift = math.nan
            else:
                recorder.multipliers[k - 1] = step.start.multipliers
                correction = system.stabilizer.correct(system, step.q, step.v, k * dt)
                recorder.corrections[k] = correction.iterations
                q_next, v_next = correction.q, correction.v
                drift = recorder.record(k, k * dt, q_next, v_next)
                # a velocity residual that would carry the constraint past the limit within one step
                drift = max(drift, recorder.velocity_drift[k] * dt)
            if not drift <= drift_limit:
                recorder.wall_time = time.perf_counter() - start
                partial = recorder.trajectory(k, _info(scene, system, integrator, dt, report))
                reason = (
                    "a non-finite state"
                    if not np.isfinite(drift)
                    else f"drift {drift:.3g} > {drift_limit:g} (position residual, or velocity residual x dt)"
                )
                raise DivergenceError(
                    f"simulation diverged at t = {k * dt:.6g} s (step {k}): {reason}; the last finite state is at "
                    f"t = {t:.6g} s. Reduce dt, change the gains, or use another method.",
                    t,
                    q,
                    v,
                    partial,
                )
            q, v, t = q_next, v_next, k * dt
            if bar is not None:
                bar.update(1)
        recorder.multipliers[steps] = system.dynamics(q, v, t).multipliers
    recorder.wall_time = time.perf_counter() - start
    return recorder.trajectory(steps, _info(scene, system, integrator, dt, report))


class _Recorder:
    def __init__(self, system: ConstrainedSystem, steps: int) -> None:
        self.system = system
        n = steps + 1
        self.t = np.zeros(n)
        self.q = np.zeros((n, system.model.nq))
        self.v = np.zeros((n, system.model.nv))
        self.multipliers = np.full((n, system.constraints.rows), np.nan)
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
        values = self.system.constraint_values(q, v, t)
        self.position_drift[k] = np.max(np.abs(values.phi), initial=0.0)
        self.velocity_drift[k] = np.max(np.abs(values.velocity_residual), initial=0.0)
        self.energy[k] = self.system.energy(q, v)
        radius = self.system.stabilizer.spectral_radius(self.system, q, v, t)
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

    def trajectory(self, last: int, info: dict[str, Any]) -> Trajectory:
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
    scene: Scene, system: ConstrainedSystem, integrator: str, dt: float, report: AssemblyReport | None
) -> dict[str, Any]:
    constraints = system.constraints
    return {
        "scene": scene.name,
        "method": system.stabilizer.name,
        "integrator": integrator,
        "solver": system.solver.name,
        "solver_fallbacks": system.solver.fallbacks,
        "dt": dt,
        "parameters": system.stabilizer.parameters(),
        "scene_parameters": scene.parameters,
        "constraint_rows": {name: [s.start, s.stop] for name, s in constraints.slices.items()},
        "force_frames": {c.name: c.force_frame for c in constraints.constraints},
        "assembly": None
        if report is None
        else {
            "iterations": report.iterations,
            "residual": report.residual,
            "velocity_residual": report.velocity_residual,
        },
    }


def _refuse_unstable_gains(system: ConstrainedSystem, q: np.ndarray, v: np.ndarray, strict: bool) -> float | None:
    """Warn (or refuse with ``strict``) before stepping when rho(R(tau W)) >= 1 at the start; returns rho."""
    stabilizer = system.stabilizer
    radius = stabilizer.spectral_radius(system, q, v, 0.0)
    if radius is None or radius < 1.0:
        return radius
    bound = largest_stable_step(*stabilizer.deviation_gains(system, q, v), stabilizer.scheme)
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
