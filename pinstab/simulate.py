"""``simulate()``: assemble, then step a scene with a stabilizer, an integrator and a KKT backend."""

from __future__ import annotations

import dataclasses
import sys
import time
import warnings
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping
from contextlib import closing, contextmanager, nullcontext
from pathlib import Path
from typing import Any

import numpy as np

from .assembly import AssemblyReport, assemble
from .constraints import PointContact, RowKind
from .constraints.joint_limits import JointLimit, check_start_inside, joint_limits
from .contact.modes import STOP_KINDS, stop_kind
from .errors import (
    ContactInfeasibleError,
    DivergenceError,
    JointLimitsWarning,
    PinstabError,
    UnstableGainsError,
    UnstableGainsWarning,
)
from .files import check_output
from .integration import (
    CHECK_STEPS,
    INTEGRATORS,
    AdaptiveLoop,
    ErrorControl,
    StepLoop,
    StreamedRecords,
    TimeGrid,
    embedded_pairs,
)
from .integration.contact_stepping import ContactStepper
from .integration.events import LIMIT_SLACK, EventLoop, RunEnd
from .memory import RUN_DATA_COPIES, data_bytes, exhausted, named_when_exhausted, require, samples_bytes
from .runinfo import RunInfo
from .scene import Scene, load_scene
from .series import StateSeries
from .solvers.contact_modes import ModeDynamics, PlaneContactGeometry, plane_geometries
from .solvers.ncp import NcpSolver
from .stability import largest_stable_step
from .stream import BLOCK, StreamWriter, h5py_module
from .system import ConstrainedSystem, build_system
from .trajectory import StreamedTrajectory, Trajectory
from .validation import relative_tolerance
from .zero_dynamics import warn_runaway

DEFAULT_DT = 1e-3  # [s] the time step of a scene without [run] dt
HELD_ONLY = ("method", "integrator", "solver")  # simulate()'s options that event-driven contacts have no use for
ALTERNATIVE = {  # what else to try when a method's gains are predicted unstable
    "mukharlyamov": "or leave the gains to the method (no --kp, --kd: placed for the step and the integrator) or "
    "lower --decay",
    None: "or use --method mukharlyamov, whose automatic gains are placed for the step and the integrator",
}
DEFAULT_DRIFT_LIMIT = 1.0  # [m or rad]: beyond this the run is declared diverged
MIN_RTOL = 1e-14  # below this a relative error estimate is rounding
EVENT_RTOL = 1e-10  # the default tolerance of event-driven contacts
MAX_EVENT_CONTACTS = 8  # scenes of plane contacts only, at most this many, default to event-driven contacts
STREAM_WINDOW = BLOCK + CHECK_STEPS + 16  # samples a streamed run holds: a block and a chunk of steps (a passage's)


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`simulate`: a KeyboardInterrupt carrying the partial trajectory.

    Attributes:
        trajectory: the samples up to the last checked state (at most ``CHECK_STEPS`` steps before the
            interruption), with its run info.
    """

    def __init__(self, trajectory: Trajectory) -> None:
        super().__init__(f"interrupted at t = {trajectory.info.t_end:.6g} s (step {trajectory.steps})")
        self.trajectory = trajectory


@named_when_exhausted("a run (simulate)")
def simulate(
    scene: Scene | str | Path,
    method: str = "baumgarte",
    integrator: str = "rk4",
    dt: float | None = None,
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
    record_every: int = 1,
    rtol: float | None = None,
    atol: float | None = None,
    contacts: str | None = None,
    stop_on: tuple[str, ...] | frozenset[str] = (),
    assembly_tol: float | None = None,
    limits: bool = True,
    stream: str | Path | None = None,
    **method_options: Any,
) -> Trajectory | StreamedTrajectory:
    """Simulate a scene.

    Args:
        scene: a :class:`Scene`, a scene file path or a bundled scene name.
        method: a registered stabilization method (``none``, ``baumgarte``, ``mukharlyamov``,
            ``projection``, ``post``, ``pinocchio``, or one registered by the user).
        integrator: a registered integrator (``euler``, ``semi-implicit-euler``, ``heun``, ``rk4``).
        dt: time step [s] (default: the scene's ``[run] dt``, else :data:`DEFAULT_DT`); the last step is shortened
            so that the run ends at ``duration`` exactly.
        duration: simulated time [s].
        solver: a registered KKT backend (``proxsuite``, ``pinocchio``, ``dense``); None (default):
            Pinocchio's own algorithm where the scene and the method allow it (the native path,
            ``info.path``), else the method's backend or ``proxsuite``.
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
        record_every: keep a sample every this many steps (and the last); every step is stepped and
            checked either way.
        rtol: with an embedded pair (``dopri5``, ``dop853``), control the step by its error estimate with
            this relative tolerance [-] (:mod:`pinstab.integration.adaptive`); ``dt`` is then the step of
            the samples (taken from the dense output), not of the integration.
        atol: the absolute tolerance [rad, m, rad/s, m/s] of the error control (default: ``rtol``).
        contacts: ``event``: the scene's plane contacts switch between sticking, sliding and separated at
            located events, with impacts (:mod:`pinstab.integration.events`; error-controlled ``dop853``,
            rtol default :data:`EVENT_RTOL`); ``stepping``: time-stepping contacts, a velocity-level Moreau-Jean
            step of ``dt`` with impulses on the exact round cone (Pinocchio's ADMM in NCP mode;
            :mod:`pinstab.integration.contact_stepping`), modes read from the impulses; both list every mode
            change in ``info.contact_events``; None: they are held as constraint rows (see
            :func:`default_contacts`).
        stop_on: with ``contacts="event"``, the kinds of contact event that end the run
            (:data:`~pinstab.contact.modes.STOP_KINDS`: ``slip``, a contact at rest starts sliding;
            ``separation``, a touching contact opens): the trajectory ends at the first such event, with
            ``info.stopped`` saying which.
        assembly_tol: the closure residual the assembly accepts, relative to the mechanism's size [-] (in (0, 1);
            default: the scene's ``[assembly] tolerance``, else 1e-10; :func:`~pinstab.assembly.assemble`).
        limits: hold the robot's joint limits (:mod:`pinstab.constraints.joint_limits`) as unilateral rows with
            impacts. A run whose samples stay inside them is the run without them (the held path; its
            ``info.limits_active_s`` empty); a run that leaves them is run again from the start by the event path
            (:mod:`pinstab.integration.events`: error-controlled dop853, the scene's closures held, ``method``,
            ``integrator`` and ``solver`` unused; ``info.path_reason`` names the first limit left), each limit's
            time held in ``info.limits_active_s`` and its switches in ``info.contact_events``. Event-driven
            contacts take the limits from the start; time-stepping contacts do not handle them. False: limits
            ignored. ``info.limits_active_s`` is None when they are ignored or the model has none.
        stream: an HDF5 file (``.h5``; needs ``h5py``, the ``stream`` extra) the samples are written to as the run
            proceeds, a block at a time (:mod:`pinstab.stream`), instead of being kept in memory: memory stays
            bounded whatever the duration. The derived series are computed into it block by block once the run
            ends; the overlap check of scenes with collision geometry and the servo's zero-dynamics check are
            not made.

    Returns:
        The :class:`Trajectory`; its drift, energy and multiplier series are computed from the kept
        samples when first read. With ``stream``: a :class:`~pinstab.trajectory.StreamedTrajectory` (info and
        summary; ``load()`` reads the file whole).

    Raises:
        DivergenceError: non-finite state, drift above ``drift_limit``, or a solve or projection that
            fails on a state reached inside a step; carries the last finite state, its time, the time of
            the failed step (``diverged_at``), the partial trajectory (ending with the failed step's
            sample) and ``finite_trajectory``, which ends at the last finite state.
        Interrupted: Ctrl-C (a KeyboardInterrupt) while stepping; carries the partial trajectory.
        ContactInfeasibleError: contacts that cannot hold (held rows), or no consistent contact modes
            (:class:`~pinstab.errors.PainleveError`, event-driven); raised once the run started, it carries
            the partial trajectory (``trajectory``, up to the last good state, ``info.stopped`` naming the
            failure).
        UnstableGainsError: with ``strict``, gains predicted unstable, before any step.

    Warns:
        UnstableGainsWarning: gains predicted unstable, before any step (without ``strict``).
        ZeroDynamicsWarning: with servos, a coordinate they leave free ran away (its speed grew more than
            tenfold: :mod:`pinstab.zero_dynamics`); ``trajectory.zero_dynamics`` has the figures.
        PenetrationWarning: a link of the robot and an object overlap deeper than at the start, beyond the
            tolerance, at the kept samples (:mod:`pinstab.contact.collisions`).
    """
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if dt is None:
        dt = DEFAULT_DT if scene.step is None else scene.step
    kinds = stop_kinds(stop_on, contacts)
    if stream is not None:
        h5py_module()
        check_output(stream, ".h5", "streamed run")
    if assembly_tol is not None:
        relative_tolerance(assembly_tol, "assembly_tol")
    if contacts == "stepping":
        return _checked(scene, _simulate_stepping(scene, dt, duration, record_every, q0, v0, progress, stream))
    table = joint_limits(scene.model).limits if limits else []
    start = scene.q0 if q0 is None else np.asarray(q0, dtype=float)
    if table and start.shape == scene.q0.shape:
        check_start_inside(table, start, scene.name)
    if contacts is not None:
        events = _simulate_events(
            scene, contacts, dt, duration, rtol, atol, record_every, q0, v0, progress, kinds, table, stream=stream
        )
        return _checked(scene, events)
    trajectory = _simulate_held(
        scene, method, integrator, dt, duration, solver, solver_options, strict, drift_limit, progress, q0, v0,
        assemble_initial, assembly_tol, record_every, rtol, atol, method_options, stream,
    )  # fmt: skip
    if not table:
        return _checked(scene, trajectory)
    left = limit_left(trajectory, table)
    if left is None:
        trajectory.info.limits_active_s = {}
        return _checked(scene, trajectory)
    reason = f"joint limits: {left[0].name} left at t = {left[1]:.6g} s on the held path"
    refused = _not_event_driven(scene)
    if refused:
        warnings.warn(
            JointLimitsWarning(
                f"scene {scene.name}: {reason}, but its constraints {', '.join(refused)} are not closures or "
                "event-driven contacts, which the joint limits' event path needs: the run ignores the limits"
            ),
            stacklevel=2,
        )
        return _checked(scene, trajectory)
    events = _simulate_events(
        scene, "event", dt, duration, rtol, atol, record_every, q0, v0, progress, frozenset(), table, reason, stream
    )
    return _checked(scene, events)


def _not_event_driven(scene: Scene) -> list[str]:
    """The constraints of a scene that the event path cannot take with joint limits: those neither event-driven
    contacts nor holonomic equality rows (servo rows, held contacts, rolling and other Pfaffian rows, which it
    would hold without their drift correction)."""
    names = {g.name for g in plane_geometries(scene.constraints)}
    return [
        c.name
        for c in scene.constraints
        if c.name not in names and (c.row_kind is not RowKind.EQUALITY or c.prescribed or not c.holonomic)
    ]


def limit_left(
    trajectory: Trajectory | StreamedTrajectory, limits: list[JointLimit]
) -> tuple[JointLimit, float] | None:
    """The first joint limit a trajectory's samples leave (beyond :data:`LIMIT_SLACK`) and when [s], or None (a
    streamed run's file read a block at a time)."""
    if isinstance(trajectory, StreamedTrajectory):
        with closing(trajectory.blocks()) as blocks:  # the file closed before the event path writes it again
            return _first_left(blocks, limits)
    return _first_left([(trajectory.t, trajectory.q)], limits)


def _first_left(
    blocks: Iterable[tuple[np.ndarray, np.ndarray]], limits: list[JointLimit]
) -> tuple[JointLimit, float] | None:
    """:func:`limit_left` over consecutive blocks of samples (t [s], q)."""
    for t, q in blocks:
        first = None
        for limit in limits:
            outside = np.flatnonzero(limit.sign * (q[:, limit.index_q] - limit.bound) < -LIMIT_SLACK)
            if outside.size and (first is None or t[outside[0]] < first[1]):
                first = (limit, float(t[outside[0]]))
        if first is not None:
            return first
    return None


def _simulate_held(
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
    q0: np.ndarray | None,
    v0: np.ndarray | None,
    assemble_initial: bool,
    assembly_tol: float | None,
    record_every: int,
    rtol: float | None,
    atol: float | None,
    method_options: Mapping[str, Any],
    stream: str | Path | None,
) -> Trajectory | StreamedTrajectory:
    """:func:`simulate` with the scene's constraints held as rows by a stabilization method, limits ignored."""
    carried = [c.name for c in scene.constraints if getattr(c, "plane_frame", None) is not None]
    if carried:
        raise PinstabError(
            f"scene {scene.name}: contact {carried[0]} touches a plane carried by a body (frame_b), which only "
            "event-driven contacts model; run it with contacts='event'"
        )
    grid = TimeGrid.of(dt, duration, record_every)
    if isinstance(drift_limit, bool) or not isinstance(drift_limit, int | float) or not drift_limit > 0:
        raise PinstabError(f"drift_limit must be a positive number, got {drift_limit!r}")
    control = None if rtol is None and atol is None else error_control(rtol, atol, integrator)
    _require_memory(scene, grid, record_every, stream)
    system = build_system(scene, method, solver, solver_options, **method_options)
    stepper = INTEGRATORS.build(integrator, system)
    if control is not None and system.stabilizer.step_dependent:
        raise PinstabError(
            f"method {method} places its automatic gains for one fixed step; with rtol (error control, steps of "
            "varying length) give its gains (kp, kd), or use baumgarte, projection or post"
        )
    model = system.model
    q = scene.q0.copy() if q0 is None else np.asarray(q0, dtype=float).copy()
    v = scene.v0.copy() if v0 is None else np.asarray(v0, dtype=float).copy()
    if q.shape != (model.nq,) or v.shape != (model.nv,):
        raise PinstabError(f"q0 must have {model.nq} entries and v0 {model.nv}")
    report: AssemblyReport | None = None
    if assemble_initial:
        report = assemble(model, q, v, tolerance=assembly_tol)
        q, v = report.q, report.v
    system.bind(grid.dt, integrator, q)
    # with error control the steps vary: the control, not a criterion at one step, keeps them stable
    start_radius = _refuse_unstable_gains(system, q, v, strict) if control is None else None
    warned = start_radius is not None and start_radius >= 1

    info = _info(scene, system, integrator, grid, report, method, solver_options, record_every)
    if control is None:
        loop = StepLoop(system, stepper, grid, record_every, drift_limit, warned)
    else:
        loop = AdaptiveLoop(system, stepper, grid, record_every, drift_limit, warned, control)
    _stream_records(loop, stream, info)
    bar = _progress_bar(grid.steps, scene.name, progress)
    # a diverging run overflows before it is caught and reported; numpy's warnings would only add noise
    with (
        np.errstate(over="ignore", invalid="ignore"),
        _kept_when_stopped(loop, system, info) as elapsed,
        nullcontext() if bar is None else closing(bar),
    ):
        loop.run(q, v, bar)
    trajectory = _trajectory(loop, system, info, elapsed())
    if system.servo is not None and stream is None:
        warn_runaway(trajectory.zero_dynamics, scene.name)
    return trajectory


def _checked(scene: Scene, trajectory: Trajectory | StreamedTrajectory) -> Trajectory | StreamedTrajectory:
    """``trajectory``, after warning of the robot-object overlaps at its kept samples
    (:meth:`~pinstab.contact.collisions.CollisionCheck.warn_during`); a streamed run instead gets its completed
    info written to its file."""
    if isinstance(trajectory, StreamedTrajectory):
        trajectory.write_info()  # as completed after the file was finished
    elif scene.collisions is not None:
        scene.collisions.warn_during(trajectory.t, trajectory.q, scene.name)
    return trajectory


@contextmanager
def _kept_when_stopped(loop: StepLoop, system: ConstrainedSystem, info: RunInfo) -> Iterator[Callable[[], float]]:
    """Around a run's stepping, yielding its wall time so far [s]: a run that stops early carries the samples it
    kept: a DivergenceError its ``trajectory`` and ``finite_trajectory``, Ctrl-C an :class:`Interrupted`, a
    ContactInfeasibleError its ``trajectory`` (``info.stopped`` naming the failure), a MemoryError becomes a
    MemoryBudgetError with its ``trajectory``."""
    start = time.perf_counter()

    def elapsed() -> float:
        return time.perf_counter() - start

    try:
        yield elapsed
    except DivergenceError as exc:
        wall_time = elapsed()
        finite = loop.records.count - 1  # without the failed step's sample
        finite_info = dataclasses.replace(info)
        exc.trajectory = _trajectory(loop, system, info, wall_time)
        exc.finite_trajectory = (
            exc.trajectory if _streamed(loop) else _trajectory(loop, system, finite_info, wall_time, finite)
        )
        raise
    except KeyboardInterrupt:
        raise Interrupted(_trajectory(loop, system, info, elapsed(), cut_off=True)) from None
    except ContactInfeasibleError as exc:
        exc.trajectory = _trajectory(loop, system, info, elapsed())
        info.stopped = failure_stop(exc, info.t_end)
        if _streamed(loop):
            exc.trajectory.write_info()
        raise
    except MemoryError as error:
        raise exhausted(f"the run of scene {info.scene}", error, _trajectory(loop, system, info, elapsed())) from None


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
    """(the scene's unilateral contacts as event-driven geometries: plane contacts and point-friction or
    frictionless grasp contacts, the names of its other constraints)."""
    geometries = plane_geometries(scene.constraints)
    names = {g.name for g in geometries}
    return geometries, [c.name for c in scene.constraints if c.name not in names]


def default_contacts(scene: Scene) -> str | None:
    """``event`` for a scene whose constraints are plane contacts only, at most :data:`MAX_EVENT_CONTACTS` of
    them; None (contacts held as constraint rows) otherwise (grasps are held unless asked)."""
    plane = [c for c in scene.constraints if isinstance(c, PointContact)]
    many = len(plane) > MAX_EVENT_CONTACTS
    return "event" if plane and len(plane) == len(scene.constraints) and not many else None


def failure_stop(error: PinstabError, t: float) -> dict[str, Any]:
    """``info.stopped`` of a run ended by ``error`` with its last state at t [s]."""
    return {"reason": "contact failure", "t": t, "error": type(error).__name__, "message": str(error)}


def _simulate_events(
    scene: Scene,
    contacts: str,
    dt: float,
    duration: float,
    rtol: float | None,
    atol: float | None,
    record_every: int,
    q0: np.ndarray | None,
    v0: np.ndarray | None,
    progress: bool,
    stop_on: frozenset[str] = frozenset(),
    limits: list[JointLimit] | None = None,
    reason: str = "event-driven contacts",
    stream: str | Path | None = None,
) -> Trajectory | StreamedTrajectory:
    """:func:`simulate` with event-driven contacts (``contacts="event"``) and joint limits, ending at the first
    event of a kind in ``stop_on``; ``reason``: the run's ``path_reason``."""
    if contacts != "event":
        raise PinstabError(f"contacts {contacts!r} is not a contact treatment; valid: event, stepping")
    limits = limits or []
    geometries, system, q, v = _contact_system(scene, q0, v0, closures=bool(limits))
    grid = TimeGrid.of(dt, duration, record_every)
    control = error_control(EVENT_RTOL if rtol is None and atol is None else rtol, atol, "dop853")
    system.bind(grid.dt, "dop853", q)
    dynamics = ModeDynamics(system.model, geometries, 0.0, 0.0, limits)
    system.acceleration = dynamics.acceleration
    system.path, system.path_reason = "contact-events", reason
    stepper = INTEGRATORS.build("dop853", system)
    info = _info(scene, system, "dop853", grid, None, "none", None, record_every)
    loop = EventLoop(system, stepper, grid, record_every, DEFAULT_DRIFT_LIMIT, False, control, dynamics)
    loop.stop_on = stop_on
    _stream_records(loop, stream, info)
    bar = _progress_bar(grid.steps, scene.name, progress)
    end = None
    with _kept_when_stopped(loop, system, info) as elapsed, nullcontext() if bar is None else closing(bar):
        try:
            loop.start(q, v)
            loop.run(q, v, bar)
        except RunEnd as exc:
            end = exc
            loop.records.end_with((loop.grid_index(end.t), float(end.t), end.q, end.v))
            if end.error is not None:
                raise end.error from None
    trajectory = _trajectory(loop, system, info, elapsed())
    if limits:
        info.limits_active_s = loop.limit_times(info.t_end)
    if end is not None:
        event = end.event
        info.stopped = {"reason": stop_kind(event), "t": info.t_end, "contact": event.contact, "event": event.to_dict()}
    return trajectory


def _simulate_stepping(
    scene: Scene,
    dt: float,
    duration: float,
    record_every: int,
    q0: np.ndarray | None,
    v0: np.ndarray | None,
    progress: bool,
    stream: str | Path | None,
) -> Trajectory | StreamedTrajectory:
    """:func:`simulate` with time-stepping contacts (``contacts="stepping"``)."""
    geometries, system, q, v = _contact_system(scene, q0, v0)
    grid = TimeGrid.of(dt, duration, record_every)
    system.bind(grid.dt, "semi-implicit-euler", q)
    dynamics = ModeDynamics(system.model, geometries, 0.0, 0.0)
    stepper = ContactStepper(system, dynamics, NcpSolver(3 * len(geometries)))
    system.path, system.path_reason = "contact-stepping", "time-stepping contacts (Moreau-Jean, ADMM in NCP mode)"
    info = _info(scene, system, stepper.name, grid, None, "none", None, record_every)
    info.solver = "pinocchio-admm"
    loop = StepLoop(system, stepper, grid, record_every, DEFAULT_DRIFT_LIMIT, False)
    _stream_records(loop, stream, info)
    bar = _progress_bar(grid.steps, scene.name, progress)
    with _kept_when_stopped(loop, system, info) as elapsed, nullcontext() if bar is None else closing(bar):
        loop.run(q, v, bar)
    return _trajectory(loop, system, info, elapsed())


def _contact_system(
    scene: Scene, q0: np.ndarray | None, v0: np.ndarray | None, closures: bool = False
) -> tuple[list[PlaneContactGeometry], ConstrainedSystem, np.ndarray, np.ndarray]:
    """The unilateral contacts of a scene (:func:`event_contacts`), the system of its bodies without them and the
    start state. Its other constraints must be equality rows kept in the system (assembled at the start) with
    ``closures`` (joint limits), else there must be none and some contact.

    Raises:
        PinstabError: a scene whose constraints do not fit (naming them).
    """
    geometries, others = event_contacts(scene)
    kept = [c for c in scene.constraints if c.name in others]
    refused = _not_event_driven(scene) if closures else others
    if (not geometries and not closures) or refused:
        raise PinstabError(
            f"scene {scene.name}: event-driven and time-stepping contacts take scenes whose constraints are plane "
            "contacts or point-friction / frictionless grasp contacts (with joint limits, closures too)"
            + (f"; not yet {', '.join(refused)}" if refused else "; it has none")
        )
    # the modes' dynamics replace the system's accelerations: with closures, off Pinocchio's native path
    system = build_system(dataclasses.replace(scene, constraints=kept), "none", "dense") if closures else None
    system = system or build_system(dataclasses.replace(scene, constraints=[]), "none")
    q = scene.q0.copy() if q0 is None else np.asarray(q0, dtype=float).copy()
    v = scene.v0.copy() if v0 is None else np.asarray(v0, dtype=float).copy()
    if closures and kept:
        report = assemble(system.model, q, v)
        q, v = report.q, report.v
    return geometries, system, q, v


def error_control(rtol: float | None, atol: float | None, integrator: str) -> ErrorControl:
    """The tolerances of an error-controlled run (``atol`` defaults to ``rtol``).

    Raises:
        PinstabError: a tolerance that is not a positive number (rtol at least 1e-14: below it the estimate is
            rounding), or an integrator without an error estimator (naming those that have one).
    """
    pairs = embedded_pairs()
    if integrator not in pairs:
        raise PinstabError(
            f"integrator {integrator!r} has no error estimator for rtol/atol; integrators with one: {', '.join(pairs)}"
        )
    rtol = atol if rtol is None else rtol
    atol = rtol if atol is None else atol
    for label, value, lowest in (("rtol", rtol, MIN_RTOL), ("atol", atol, 0.0)):
        if isinstance(value, bool) or not isinstance(value, int | float) or not lowest < value < 1.0:
            raise PinstabError(f"{label} must be a number in ({lowest:g}, 1), got {value!r}")
    return ErrorControl(float(rtol), float(atol))


def kept_samples(scene: Scene, steps: int, record_every: int) -> tuple[int, int]:
    """(how many samples a run of ``steps`` steps keeping one every ``record_every`` holds at most, their
    estimated size [bytes])."""
    samples = steps // record_every + 2
    model = scene.model
    return samples, samples_bytes(samples, model.nq, model.nv, scene.constraint_set.rows)


def _require_memory(scene: Scene, grid: TimeGrid, record_every: int, stream: str | Path | None) -> None:
    """Refuse (MemoryBudgetError) a run whose Pinocchio data and kept samples (a window of them when streamed)
    would exceed the budget."""
    model = scene.model
    samples, size = kept_samples(scene, grid.steps if stream is None else STREAM_WINDOW * record_every, record_every)
    require(
        {
            f"Pinocchio data ({RUN_DATA_COPIES} copies, nv = {model.nv})": RUN_DATA_COPIES
            * data_bytes(model.nv, model.njoints),
            f"{samples:,} kept samples": size,
        },
        f"a run of scene {scene.name} ({grid.steps:,} steps, a sample kept every {record_every})",
        "keep fewer samples (--record-every, record_every), stream them to disk (--stream FILE.h5, stream), use a "
        "larger step or a shorter duration",
    )


def _stream_records(loop: StepLoop, stream: str | Path | None, info: RunInfo) -> None:
    """With ``stream``, the loop keeps its samples in :class:`StreamedRecords` writing to that file."""
    if stream is None:
        return
    model, rows = loop.system.model, loop.system.model.constraints.rows
    writer = StreamWriter(stream, info, model.nq, model.nv, rows)
    loop.records = StreamedRecords(loop.grid, loop.every, model.nq, model.nv, writer, BLOCK, STREAM_WINDOW - BLOCK)


def _streamed(loop: StepLoop) -> bool:
    """Whether the loop streams its samples to a file."""
    return isinstance(loop.records, StreamedRecords)


def _trajectory(
    loop: StepLoop,
    system: ConstrainedSystem,
    info: RunInfo,
    wall_time: float,
    samples: int | None = None,
    cut_off: bool = False,
) -> Trajectory | StreamedTrajectory:
    """The trajectory of the first ``samples`` samples kept (default: all kept so far), with the run info
    completed; wall_time [s]. A streamed run's file is finished: its last samples written and, unless the run
    was ``cut_off`` (interrupted), its derived series."""
    records = loop.records
    n = records.count if samples is None else samples
    slot = records.slot(n - 1)
    info.steps, info.t_end = int(records.steps[slot]), float(records.t[slot])
    info.solver_statistics = system.statistics
    info.correction_iterations_total, info.correction_iterations_max = loop.correction_total, loop.correction_max
    watch = getattr(loop, "watch", None)  # none in a run that ended at its start, before stepping
    info.passages = [] if watch is None else [p.to_dict() for p in watch.passages if p.t <= info.t_end]
    events = loop.events if isinstance(loop, EventLoop) else getattr(loop.stepper, "events", None)
    if events is not None:
        info.contact_events = [event.to_dict() for event in events if event.t <= info.t_end]
    if isinstance(loop, AdaptiveLoop):
        info.error_control = loop.control.summary()
    if _streamed(loop):
        records.finish()
        records.sink.close()
        return StreamedTrajectory.complete(records.sink.path, info, wall_time, None if cut_off else StateSeries(system))
    return Trajectory(  # views of the samples: no second copy of a long run
        records.t[:n],
        records.q[:n],
        records.v[:n],
        wall_time,
        info,
        correction_iterations=records.corrections[:n],
        series=StateSeries(system),
    )


def _info(
    scene: Scene,
    system: ConstrainedSystem,
    integrator: str,
    grid: TimeGrid,
    report: AssemblyReport | None,
    method: str,
    solver_options: Mapping[str, Any] | None,
    record_every: int,
) -> RunInfo:
    constraints = system.model.constraints
    return RunInfo(
        scene=scene.name,
        method=method,
        integrator=integrator,
        solver="pinocchio" if system.path == "native" else ("servo" if system.servo else system.solver.name),
        dt=grid.dt,
        parameters=system.stabilizer.parameters(),
        solver_options=dict(solver_options or {}),
        scene_parameters=scene.parameters,
        constraint_rows={name: [s.start, s.stop] for name, s in constraints.slices.items()},
        row_kinds={c.name: c.row_kind.value for c in constraints.constraints},
        force_frames={c.name: c.force_frame for c in constraints.constraints},
        assembly=None if report is None else report.summary(),
        path=system.path,
        path_reason=system.path_reason,
        record_every=record_every,
        controls=list(scene.actuation.names) if system.servo is not None else [],
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


def _progress_bar(steps: int, label: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=steps, desc=label, unit="step", file=sys.stderr, delay=2.0, mininterval=0.5, leave=False)
