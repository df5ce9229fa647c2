"""The held path of ``simulate()``: the scene's constraints held as rows by a stabilization method, stepped by a
fixed-step or error-controlled integrator."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from contextlib import closing, nullcontext
from pathlib import Path
from typing import Any

import numpy as np

from ..assembly import AssemblyReport, assemble
from ..constraints.base import RowKind
from ..constraints.joint_limits import LimitWatch
from ..errors import PinstabError, UnstableGainsError, UnstableGainsWarning
from ..integration import INTEGRATORS, AdaptiveLoop, ErrorControl, Integrator, StepLoop, TimeGrid
from ..model import ConstrainedModel
from ..scene import Scene
from ..solvers.impacts import REST_SPEED
from ..stability.criterion import largest_stable_step
from ..system import ConstrainedSystem, build_system
from ..trajectory import StreamedTrajectory, Trajectory
from ..zero_dynamics import warn_runaway
from .loop import (
    RunClock,
    check_drift_limit,
    error_control,
    kept_when_stopped,
    progress_bar,
    require_memory,
    run_info,
    stream_records,
    trajectory_of,
)

ALTERNATIVE = {  # what else to try when a method's gains are predicted unstable
    "mukharlyamov": "or leave the gains to the method (no --kp, --kd: placed for the step and the integrator) or "
    "lower --decay",
    None: "or use --method mukharlyamov, whose automatic gains are placed for the step and the integrator",
}


def simulate_held(
    scene: Scene,
    method: str,
    integrator: str,
    dt: float,
    duration: float,
    solver: str | None,
    solver_options: Mapping[str, Any] | None,
    strict: bool,
    drift_limit: float,
    progress: bool,
    q0: np.ndarray,
    v0: np.ndarray,
    assemble_initial: bool,
    assembly_tol: float | None,
    record_every: int,
    rtol: float | None,
    atol: float | None,
    method_options: Mapping[str, Any],
    stream: str | Path | None,
    clock: RunClock,
    limit_watch: LimitWatch | None = None,
) -> Trajectory | StreamedTrajectory:
    """:func:`simulate` with the scene's constraints held as rows by a stabilization method, limits ignored
    (``limit_watch`` fed every step's state); timed by the call's ``clock``."""
    grid = TimeGrid.of(dt, duration, record_every)
    check_drift_limit(drift_limit)
    control = None if rtol is None and atol is None else error_control(rtol, atol, integrator)
    require_memory(scene, grid, record_every, stream)
    system, stepper = held_system(scene, method, integrator, solver, solver_options, control, method_options)
    model = system.model
    q, v = q0.copy(), v0.copy()
    report: AssemblyReport | None = None
    if assemble_initial:
        report = assemble(model, q, v, tolerance=assembly_tol)
        q, v = report.q, report.v
    refuse_separating_contacts(system.model, q, v, scene.name)
    system.bind(grid.dt, integrator, q, varying=control is not None)
    # with error control the steps vary: the control, not a criterion at one step, keeps them stable
    start_radius = _refuse_unstable_gains(system, q, v, strict) if control is None else None
    warned = start_radius is not None and start_radius >= 1

    info = run_info(scene, system, integrator, grid, report, method, solver_options, record_every)
    if control is None:
        loop = StepLoop(system, stepper, grid, record_every, drift_limit, warned)
    else:
        loop = AdaptiveLoop(system, stepper, grid, record_every, drift_limit, warned, control)
    if limit_watch is not None:
        loop.watch_limits(limit_watch)
    stream_records(loop, stream, info)
    bar = progress_bar(grid.steps, scene.name, progress)
    # a diverging run overflows before it is caught and reported; numpy's warnings would only add noise
    with (
        np.errstate(over="ignore", invalid="ignore"),
        kept_when_stopped(loop, system, info, clock),
        nullcontext() if bar is None else closing(bar),
    ):
        loop.run(q, v, bar)
    trajectory = trajectory_of(loop, system, info, clock)
    if system.servo is not None and stream is None:
        warn_runaway(trajectory.zero_dynamics, scene.name)
    return trajectory


def held_system(
    scene: Scene,
    method: str,
    integrator: str,
    solver: str | None,
    solver_options: Mapping[str, Any] | None,
    control: ErrorControl | None,
    method_options: Mapping[str, Any],
) -> tuple[ConstrainedSystem, Integrator]:
    """The system and the integrator of the held path (:func:`simulate_held`), refused before any step: a contact on
    a plane carried by a body, a method and a solver that do not go together or a solver that does not take the
    scene's rows (:func:`~pinstab.system.build_system`), a method configured for fixed steps under error ``control``
    (steps of varying length: :meth:`~pinstab.stabilizers.base.Stabilizer.error_control_obstacle`), a sphere contact
    (``radius``) with friction (it rolls). A sweep checks its points with it.

    Raises:
        PinstabError (SolverError for the solver's refusals).
    """
    carried = [c.name for c in scene.constraints if getattr(c, "plane_frame", None) is not None]
    if carried:
        raise PinstabError(
            f"scene {scene.name}: contact {carried[0]} touches a plane carried by a body (frame_b), which only "
            "event-driven contacts model; run it with contacts='event'"
        )
    rolling = [c for c in scene.constraints if getattr(c, "radius", 0.0) and getattr(c, "friction", None)]
    if rolling:
        contact = rolling[0]
        raise PinstabError(
            f"scene {scene.name}: contact {contact.name} is a sphere (radius {contact.radius:g} m) with friction "
            f"(mu {contact.friction.mu:g}): sticking, it rolls, its touching point moving over the plane, which held "
            "rows (a point held at a fixed anchor) do not model; run it with contacts='event' or 'stepping' "
            "(--contacts event|stepping), or drop its mu"
        )
    system = build_system(scene, method, solver, solver_options, **method_options)
    stepper = INTEGRATORS.build(integrator, system)
    obstacle = None if control is None else system.stabilizer.error_control_obstacle()
    if obstacle is not None:
        raise PinstabError(f"method {method} {obstacle}")
    return system, stepper


def refuse_separating_contacts(model: ConstrainedModel, q: np.ndarray, v: np.ndarray, scene: str) -> None:
    """Refuse a start (q, v) of ``model`` at which a held contact (a block of unilateral rows, or of cone rows: its
    first row the normal) separates from its plane faster than :data:`~pinstab.solvers.impacts.REST_SPEED` [m/s]: a
    spin about a point off the contact's centre lifts it. Held rows keep a contact touching: the row would push
    while the point rises (the force doing work, energy created) instead of letting it fly; event-driven contacts
    let it open.

    Raises:
        PinstabError: naming the contact, its separating speed [m/s] and the alternatives.
    """
    stack = model.constraints
    contacts = [c for c in stack.constraints if c.row_kind in (RowKind.UNILATERAL, RowKind.CONE)]
    if not contacts:
        return
    rates = model.constraint_values(q, v, 0.0, model.scratch_kinematics).velocity_residual
    for contact in contacts:
        rows = stack.slices[contact.name]
        rate = float(np.max(rates[rows]) if contact.row_kind == RowKind.UNILATERAL else rates[rows.start])
        if rate > REST_SPEED:
            raise PinstabError(
                f"scene {scene}: contact {contact.name} starts separating from its plane at {rate:.6g} m/s (its "
                f"point's velocity along the normal; at most {REST_SPEED:g} m/s is at rest), which held rows (a "
                "contact kept touching) do not model: they would push the rising point back, creating energy; run "
                "it with contacts='event' (--contacts event), which lets it open, or start it at rest along the "
                "normal (initial.v)"
            )


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
    if bound > 0 and ("kp" in gains or "stiffness" in gains):
        kp = gains.get("kp", gains.get("stiffness"))
        kd = gains.get("kd", gains.get("damping"))
        advice += (
            f"; at dt = {step:g} s, gains below Kp = {kp * scale**2:.3g}, Kd = {kd * scale:.3g} (the same ratio) "
            "are stable"
        )
    message = (
        f"method {stabilizer.name} ({described}) with {stabilizer.integrator} at dt = {step:g} s: the deviation "
        f"dynamics have spectral radius rho(R(tau W)) = {radius:.4g} >= 1, so constraint errors grow instead of "
        f"decaying. {advice[0].upper() + advice[1:]}; {ALTERNATIVE.get(stabilizer.name, ALTERNATIVE[None])}."
    )
    if strict:
        raise UnstableGainsError(message)
    warnings.warn(UnstableGainsWarning(message), stacklevel=3)
    return radius
