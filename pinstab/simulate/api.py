"""``simulate()``: assemble, then step a scene with a stabilizer, an integrator and a KKT backend; the path (held,
event-driven or time-stepping contacts, joint limits) chosen from the scene and the options."""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DivergenceError, JointLimitsWarning, SolverLimitWarning
from ..files import check_output
from ..forces.joint_friction import joint_frictions
from ..memory import named_when_exhausted
from ..runinfo import SolverStatistics
from ..scene import Scene, load_scene
from ..solvers.proxsuite_ import LIMIT_STATUS
from ..stream import h5py_module
from ..trajectory import StreamedTrajectory, Trajectory
from ..validation import relative_tolerance
from .choice import ContactChoice, refuse_held_options, resolve_contacts
from .contacts import simulate_events, simulate_stepping, stop_kinds
from .held import simulate_held
from .integrator_choice import AUTO, choose_integrator
from .limits import held_limits, limit_left, limit_watch, not_event_driven
from .loop import DEFAULT_DRIFT_LIMIT, RunClock, start_state
from .threads import single_blas_thread

DEFAULT_DT = 1e-3  # [s] the time step of a scene without [run] dt
DEFAULT_METHOD = "baumgarte"  # the stabilization method of held rows
FIXED_STEP_INTEGRATOR, ERROR_CONTROLLED_INTEGRATOR = "rk4", "dop853"  # the defaults without and with rtol/atol


def default_integrator(integrator: str | None, rtol: float | None, atol: float | None) -> str:
    """``integrator``, or when it is None the default: ``dop853`` (an embedded pair) when a tolerance ``rtol`` or
    ``atol`` asks for error control, else ``rk4``; the rule of :func:`simulate` and of ``--rtol`` on the command
    line."""
    if integrator is not None:
        return integrator
    return FIXED_STEP_INTEGRATOR if rtol is None and atol is None else ERROR_CONTROLLED_INTEGRATOR


@named_when_exhausted("a run (simulate)")
@single_blas_thread
def simulate(
    scene: Scene | str | Path,
    method: str = DEFAULT_METHOD,
    integrator: str | None = None,
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
        integrator: a registered integrator (``euler``, ``semi-implicit-euler``, ``heun``, ``rk4``; the implicit
            ``implicit-euler``, ``implicit-midpoint``; ``dopri5``, ``dop853`` and the implicit ``esdirk4`` with error
            control too); None (default): ``rk4``, or ``dop853`` when ``rtol`` or ``atol`` is given
            (:func:`default_integrator`); ``auto``: that default, or an implicit integrator when the step is
            above its stability limit of a force element's stiff mode at the start
            (:mod:`~pinstab.simulate.integrator_choice`; ``info.integrator_choice`` says which and why).
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
            change in ``info.contact_events``; ``held``: they are held as constraint rows; None (default) or
            ``auto``: the scene's choice (:func:`~pinstab.simulate.choice.contact_choice`, the choice of ``pinstab
            run`` without ``--contacts``): contacts that can switch switch (event-driven, time-stepping beyond
            :data:`~pinstab.simulate.choice.MAX_EVENT_CONTACTS` declared ones), a scene that asks for a treatment
            (its ``[run] contacts``) runs it, contacts beside other constraints are held. The run reports the
            treatment, how it was chosen and why in ``info.contact_treatment``. A scene with joint friction
            (``joint-friction``) runs event-driven unless asked for another treatment, which refuses it (naming
            the joints). Event-driven and time-stepping contacts refuse the held rows' options (a ``method`` other
            than the default, ``solver``, ``solver_options``, the method's options), naming ``contacts="held"``.
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
            contacts take the limits from the start; time-stepping contacts do not hold them (a start outside them
            is refused, and leaving them warns: :class:`~pinstab.errors.JointLimitsWarning`). False: limits
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
    clock = RunClock()
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if dt is None:
        dt = DEFAULT_DT if scene.step is None else scene.step
    automatic = integrator == AUTO
    integrator = default_integrator(None if automatic else integrator, rtol, atol)
    contacts, choice = resolve_contacts(scene, contacts)
    if contacts is not None:
        unset = {"method": method == DEFAULT_METHOD, "solver": solver is None, "solver_options": not solver_options}
        refuse_held_options(scene, contacts, choice, [*(name for name, no in unset.items() if not no), *method_options])
    reason = "event-driven contacts"
    if joint_frictions(scene.forces):
        reason += " and joint friction (stick and slip at events)"
    kinds = stop_kinds(stop_on, contacts)
    if stream is not None:
        h5py_module()
        check_output(stream, ".h5", "streamed run")
    if assembly_tol is not None:
        relative_tolerance(assembly_tol, "assembly_tol")
    q0, v0 = start_state(scene, q0, v0)
    picked = None
    if automatic and contacts is None:
        controlled = rtol is not None or atol is not None
        integrator, picked = choose_integrator(scene, q0, v0, dt, integrator, controlled)
    for element in scene.forces:
        element.restart()
    table = held_limits(scene, q0, limits)  # every path refuses a start outside the limits
    watch = limit_watch(table) if table else None  # sees every step of a path that does not hold them
    if contacts == "stepping":
        stepped = simulate_stepping(scene, dt, duration, record_every, q0, v0, progress, stream, clock, watch)
        left = limit_left(stepped, watch, v0) if watch else None
        if left is not None:
            warnings.warn(
                JointLimitsWarning(
                    f"scene {scene.name}: joint limits: {left[0].name} left at t = {left[1]:.6g} s, which "
                    "time-stepping contacts do not hold: the run ignores the limits (event-driven contacts hold them)"
                ),
                stacklevel=2,
            )
        return _checked(scene, choice, stepped, clock)
    if contacts is not None:
        if rtol is None and atol is None:
            rtol = scene.rtol
        events = simulate_events(
            scene, contacts, dt, duration, rtol, atol, record_every, q0, v0, progress, kinds, table, reason, stream,
            assembly_tol, clock,
        )  # fmt: skip
        return _checked(scene, choice, events, clock)
    diverged: DivergenceError | None = None
    try:
        trajectory = simulate_held(
            scene, method, integrator, dt, duration, solver, solver_options, strict, drift_limit, progress, q0, v0,
            assemble_initial, assembly_tol, record_every, rtol, atol, method_options, stream, clock, watch,
        )  # fmt: skip
    except DivergenceError as error:  # after a limit the held path passed: the limit would have prevented it
        if watch is None or watch.left is None or error.trajectory is None:
            raise
        trajectory, diverged = error.trajectory, error
    trajectory.info.integrator_choice = picked
    if watch is None:
        return _checked(scene, choice, trajectory, clock)
    left = limit_left(trajectory, watch, v0)
    if left is None:
        trajectory.info.limits_active_s = {}
        return _checked(scene, choice, trajectory, clock)
    reason = f"joint limits: {left[0].name} left at t = {left[1]:.6g} s on the held path"
    if diverged is not None:
        reason += f", which then diverged at t = {diverged.time:.6g} s"
    refused = not_event_driven(scene)
    if refused and diverged is not None:
        raise diverged
    if refused:
        warnings.warn(
            JointLimitsWarning(
                f"scene {scene.name}: {reason}, but its constraints {', '.join(refused)} are not closures or "
                "event-driven contacts, which the joint limits' event path needs: the run ignores the limits"
            ),
            stacklevel=2,
        )
        return _checked(scene, choice, trajectory, clock)
    held = os.stat(trajectory.path).st_ino if isinstance(trajectory, StreamedTrajectory) else None
    try:
        events = simulate_events(
            scene, "event", dt, duration, rtol, atol, record_every, q0, v0, progress, frozenset(), table, reason,
            stream, assembly_tol, clock,
        )  # fmt: skip
    except BaseException:  # failed before its first row: the held run's file, which left the limits, goes too
        if held is not None and os.path.exists(trajectory.path) and os.stat(trajectory.path).st_ino == held:
            os.remove(trajectory.path)
        raise
    return _checked(scene, choice, events, clock)


def _warn_of_solver_limits(scene: Scene, statistics: SolverStatistics) -> None:
    """A :class:`~pinstab.errors.SolverLimitWarning` when ProxQP stopped at its iteration limit on some of the run's
    solves (accepted by their residuals: the worst is named)."""
    stopped = statistics.status_counts.get(LIMIT_STATUS, 0)
    if stopped:
        warnings.warn(
            SolverLimitWarning(
                f"scene {scene.name}: ProxQP stopped at its iteration limit on {stopped} of {statistics.solves} solves "
                f"(each accepted by its residual; the worst {statistics.worst_primal_residual:.3g} relative); "
                "--proxsuite-max-iter raises the limit"
            ),
            stacklevel=3,
        )


def _checked(
    scene: Scene, choice: ContactChoice | None, trajectory: Trajectory | StreamedTrajectory, clock: RunClock
) -> Trajectory | StreamedTrajectory:
    """``trajectory`` with its contact treatment's ``choice`` (``info.contact_treatment``), after warning of the robot-
    object overlaps at its kept samples (:meth:`~pinstab.contact.collisions.CollisionCheck.warn_during`), its drift and
    energy series computed (what its summary reads) and its timings set (``clock``); a streamed run instead gets its
    completed info and timings written to its file."""
    trajectory.info.contact_treatment = None if choice is None else choice.summary()
    if isinstance(trajectory, StreamedTrajectory):
        clock.stamp(trajectory)
        trajectory.write_info()  # as completed after the file was finished
        return trajectory
    if scene.collisions is not None:
        scene.collisions.warn_during(trajectory.t, trajectory.q, scene.name)
    _warn_of_solver_limits(scene, trajectory.info.solver_statistics)
    trajectory.compute_series()  # within the call: its wall time covers them
    clock.stamp(trajectory)
    return trajectory
