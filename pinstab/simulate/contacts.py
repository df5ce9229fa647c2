"""The contact paths of ``simulate()``: event-driven contacts (modes switched at located events, impacts) and
time-stepping contacts (Moreau-Jean over an NCP solve)."""

from __future__ import annotations

import dataclasses
from collections.abc import Collection
from contextlib import closing, nullcontext
from pathlib import Path
from typing import Any

import numpy as np

from ..assembly import AssemblyReport, assemble
from ..constraints.joint_limits import JointLimit, LimitWatch
from ..contact.modes import STOP_KINDS, stop_kind
from ..errors import PinstabError
from ..forces.joint_friction import JointFriction, joint_frictions
from ..integration import INTEGRATORS, StepLoop, TimeGrid
from ..integration.contact_stepping import ContactStepper
from ..integration.events import EventLoop, RunEnd
from ..scene import Scene
from ..solvers.contact_modes import ModeDynamics, PlaneContactGeometry, plane_geometries, rolling_contacts
from ..solvers.core_modes import CoreModeDynamics
from ..solvers.ncp import NcpSolver
from ..system import ConstrainedSystem, build_system
from ..trajectory import StreamedTrajectory, Trajectory
from .limits import not_event_driven
from .loop import (
    DEFAULT_DRIFT_LIMIT,
    RunClock,
    error_control,
    kept_when_stopped,
    progress_bar,
    run_info,
    stream_records,
    trajectory_of,
)

EVENT_RTOL = 1e-10  # the default tolerance of event-driven contacts
HELD_ONLY = ("method", "integrator", "solver")  # simulate()'s options that event-driven contacts have no use for


def stop_kinds(stop_on: Any, contacts: str | None) -> frozenset[str]:
    """The kinds of event a run stops on, checked: a string or a collection of :data:`STOP_KINDS`.

    Raises:
        PinstabError: an unknown kind (naming the valid ones), or kinds without event-driven contacts.
    """
    if isinstance(stop_on, str):
        stop_on = (stop_on,)
    if not isinstance(stop_on, Collection) or not all(isinstance(kind, str) for kind in stop_on):
        raise PinstabError(f"stop_on must name kinds of contact event ({', '.join(STOP_KINDS)}), got {stop_on!r}")
    kinds = frozenset(stop_on)
    unknown = sorted(kinds - set(STOP_KINDS))
    if unknown:
        raise PinstabError(f"stop_on: {unknown[0]!r} is not a kind of contact event; valid: {', '.join(STOP_KINDS)}")
    if kinds and contacts != "event":
        raise PinstabError(
            f"stop_on ({', '.join(sorted(kinds))}) ends a run at a contact event: it takes contacts='event'"
        )
    return kinds


def event_contacts(scene: Scene) -> tuple[list[PlaneContactGeometry], list[str]]:
    """(the scene's unilateral contacts as the geometries of event-driven and time-stepping contacts: plane contacts
    and grasp contacts (a soft finger's torsion a spin of its contact), the names of its other constraints)."""
    geometries = plane_geometries(scene.constraints)
    names = {g.name for g in geometries}
    return geometries, [c.name for c in scene.constraints if c.name not in names]


def simulate_events(
    scene: Scene,
    contacts: str,
    dt: float,
    duration: float,
    rtol: float | None,
    atol: float | None,
    record_every: int,
    q0: np.ndarray,
    v0: np.ndarray,
    progress: bool,
    stop_on: frozenset[str] = frozenset(),
    limits: list[JointLimit] | None = None,
    reason: str = "event-driven contacts",
    stream: str | Path | None = None,
    assembly_tol: float | None = None,
    clock: RunClock | None = None,
) -> Trajectory | StreamedTrajectory:
    """:func:`simulate` with event-driven contacts (``contacts="event"``), joint limits and joint frictions, ending at
    the first event of a kind in ``stop_on``; ``reason``: the run's ``path_reason``; ``assembly_tol``: the closures'
    assembly tolerance (see :func:`~pinstab.assembly.assemble`); ``clock``: the call's (None: one from here)."""
    clock = RunClock() if clock is None else clock
    if contacts != "event":
        raise PinstabError(f"contacts {contacts!r} is not a contact treatment; valid: event, stepping")
    limits, frictions = limits or [], joint_frictions(scene.forces)
    closures = bool(limits or frictions)
    geometries, system, q, v, report = contact_system(scene, q0, v0, closures=closures, tolerance=assembly_tol)
    grid = TimeGrid.of(dt, duration, record_every)
    control = error_control(EVENT_RTOL if rtol is None and atol is None else rtol, atol, "dop853")
    system.bind(grid.dt, "dop853", q)
    statistics = system.solver.statistics
    if closures and (not geometries or system.model.constraints.rows):  # held rows: each evaluation is the core's
        dynamics = CoreModeDynamics(system.model, geometries, limits, statistics, frictions)
    else:
        dynamics = ModeDynamics(system.model, geometries, limits, statistics, frictions)
    system.acceleration = dynamics.acceleration
    system.path, system.path_reason = "contact-events", reason
    stepper = INTEGRATORS.build("dop853", system)
    info = run_info(scene, system, "dop853", grid, report, dynamics.name, None, record_every)
    loop = EventLoop(system, stepper, grid, record_every, DEFAULT_DRIFT_LIMIT, False, control, dynamics)
    loop.stop_on = stop_on
    loop.find_contacts(scene.contact_finders)
    stream_records(loop, stream, info)
    bar = progress_bar(grid.steps, scene.name, progress)
    end = None
    with kept_when_stopped(loop, system, info, clock), nullcontext() if bar is None else closing(bar):
        try:
            loop.start(q, v)
            loop.run(q, v, bar)
        except RunEnd as exc:
            end = exc
            loop.records.end_with((loop.grid_index(end.t), float(end.t), end.q, end.v))
            if end.error is not None:
                raise end.error from None
    trajectory = trajectory_of(loop, system, info, clock)
    if limits:
        info.limits_active_s = loop.limit_times(info.t_end)
    if end is not None:
        event = end.event
        info.stopped = {"reason": stop_kind(event), "t": info.t_end, "contact": event.contact, "event": event.to_dict()}
    return trajectory


def simulate_stepping(
    scene: Scene,
    dt: float,
    duration: float,
    record_every: int,
    q0: np.ndarray,
    v0: np.ndarray,
    progress: bool,
    stream: str | Path | None,
    clock: RunClock,
    limit_watch: LimitWatch | None = None,
) -> Trajectory | StreamedTrajectory:
    """:func:`simulate` with time-stepping contacts (``contacts="stepping"``), which do not hold joint limits
    (``limit_watch`` fed every step's state), timed by the call's ``clock``."""
    grid = TimeGrid.of(dt, duration, record_every)
    system, stepper, q, v = stepping_parts(scene, grid.dt, q0, v0)
    system.path, system.path_reason = "contact-stepping", "time-stepping contacts (Moreau-Jean, ADMM in NCP mode)"
    info = run_info(scene, system, stepper.name, grid, None, "none", None, record_every)
    info.solver = "pinocchio-admm"
    loop = StepLoop(system, stepper, grid, record_every, DEFAULT_DRIFT_LIMIT, False)
    if limit_watch is not None:
        loop.watch_limits(limit_watch)
    stream_records(loop, stream, info)
    bar = progress_bar(grid.steps, scene.name, progress)
    with kept_when_stopped(loop, system, info, clock), nullcontext() if bar is None else closing(bar):
        loop.run(q, v, bar)
    return trajectory_of(loop, system, info, clock)


def stepping_parts(
    scene: Scene, dt: float, q0: np.ndarray, v0: np.ndarray, stepper: type[ContactStepper] = ContactStepper
) -> tuple[ConstrainedSystem, ContactStepper, np.ndarray, np.ndarray]:
    """The system bound to steps of ``dt`` [s], the ``stepper`` (its class: :func:`simulate_stepping`'s, or the
    NumPy reference of a benchmark or test) asking the scene's finders for contacts, and the start state of a
    time-stepping run of ``scene``.

    Raises:
        PinstabError: a scene whose contacts have rolling resistance, or whose constraints do not fit.
    """
    geometries, system, q, v, _ = contact_system(scene, q0, v0)
    rolling = rolling_contacts(geometries)
    if any(finder.spin[1] for finder in scene.contact_finders):
        rolling.append("the contacts found from geometry")
    if rolling:
        raise PinstabError(
            f"scene {scene.name}: time-stepping contacts have no rolling resistance yet (they take torsion) at "
            f"{', '.join(rolling)}; run it with event-driven contacts (--contacts event)"
        )
    system.bind(dt, "semi-implicit-euler", q)
    stepping = stepper(system, ModeDynamics(system.model, geometries), NcpSolver(3 * len(geometries)))
    stepping.find_contacts(scene.contact_finders)
    return system, stepping, q, v


def contact_system(
    scene: Scene, q0: np.ndarray, v0: np.ndarray, closures: bool = False, tolerance: float | None = None
) -> tuple[list[PlaneContactGeometry], ConstrainedSystem, np.ndarray, np.ndarray, AssemblyReport | None]:
    """The unilateral contacts of a scene (:func:`event_contacts`), the system of its bodies without them (and
    without its joint frictions, which the modes' dynamics hold), the start state and its assembly report (None
    without closures). Its other constraints must be equality rows kept
    in the system (assembled at the start, to ``tolerance``: see :func:`~pinstab.assembly.assemble`) with
    ``closures`` (joint limits), else there must be none and some contact. A sweep checks its points with it.

    Raises:
        PinstabError: a scene whose constraints do not fit (naming them).
    """
    geometries, others = event_contacts(scene)
    kept = [c for c in scene.constraints if c.name in others]
    refused = not_event_driven(scene) if closures else others
    if (not geometries and not closures) or refused:
        raise PinstabError(
            f"scene {scene.name}: event-driven and time-stepping contacts take scenes whose constraints are plane "
            "contacts or frictionless, point-friction or soft-finger grasp contacts (with joint limits, closures too)"
            + (f"; not yet {', '.join(refused)}" if refused else "; it has none")
        )
    # the modes' dynamics replace the system's accelerations (its solver counts theirs): off Pinocchio's native
    # path, whose solves and checks would count work the run does not do (kept: the closures, none without them)
    forces = [element for element in scene.forces if not isinstance(element, JointFriction)]
    system = build_system(dataclasses.replace(scene, constraints=kept, forces=forces), "none", "dense")
    q, v = q0.copy(), v0.copy()
    report = None
    if closures and kept:
        report = assemble(system.model, q, v, tolerance=tolerance)
        q, v = report.q, report.v
    return geometries, system, q, v, report
