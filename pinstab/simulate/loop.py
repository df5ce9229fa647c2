"""What every path of ``simulate()`` shares: the run's records, trajectory and info, the progress bar, the memory
budget, a run that stops early."""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from ..assembly import AssemblyReport
from ..errors import ContactInfeasibleError, DivergenceError, PinstabError, ServoInfeasibleError
from ..integration import CHECK_STEPS, AdaptiveLoop, ErrorControl, StepLoop, StreamedRecords, TimeGrid, embedded_pairs
from ..integration.events import EventLoop
from ..integration.schemes import SCHEMES
from ..kernels import SchemeStep
from ..memory import RUN_DATA_COPIES, data_bytes, exhausted, require, samples_bytes
from ..runinfo import RunInfo
from ..scene import Scene
from ..series import StateSeries
from ..stream import BLOCK, FLUSH_PERIOD, StreamWriter
from ..system import ConstrainedSystem
from ..trajectory import StreamedTrajectory, Trajectory
from ..validation import check_velocity

DEFAULT_DRIFT_LIMIT = 1.0  # [m or rad]: beyond this the run is declared diverged
MIN_RTOL = 1e-14  # below this a relative error estimate is rounding
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


def failure_stop(error: PinstabError, t: float) -> dict[str, Any]:
    """``info.stopped`` of a run ended by ``error`` (contacts or servos with no solution) with its last state at
    t [s]."""
    reason = "servo failure" if isinstance(error, ServoInfeasibleError) else "contact failure"
    return {"reason": reason, "t": t, "error": type(error).__name__, "message": str(error)}


class RunClock:
    """The wall-clock split of one :func:`~pinstab.simulate` call [s] (``time.perf_counter``): the set-up (scene
    checks, system, assembly, kernels; and whatever lies between two stepping loops: a run the joint limits send to
    the event path steps twice), the stepping loops, and the post-processing after the last (the trajectory, the
    derived series a streamed run writes, the checks on the samples)."""

    def __init__(self) -> None:
        self.began = time.perf_counter()
        self.stepping = 0.0
        self.stepped: float | None = None  # when the last stepping loop ended

    @contextmanager
    def stepping_loop(self) -> Iterator[None]:
        """Around a stepping loop (however it ends): its time counts as stepping."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self.stepped = time.perf_counter()
            self.stepping += self.stepped - start

    def split(self) -> dict[str, float]:
        """``setup_s``, ``stepping_s`` and ``post_s`` so far [s]; they add up to the time since the call began."""
        now = time.perf_counter()
        stepped = now if self.stepped is None else self.stepped
        return {"setup_s": stepped - self.began - self.stepping, "stepping_s": self.stepping, "post_s": now - stepped}

    def stamp(self, trajectory: Trajectory | StreamedTrajectory) -> None:
        """Set the trajectory's ``info.timings`` to the split so far and its ``wall_time`` to their sum [s]."""
        trajectory.info.timings = self.split()
        trajectory.wall_time = sum(trajectory.info.timings.values())


@contextmanager
def kept_when_stopped(loop: StepLoop, system: ConstrainedSystem, info: RunInfo, clock: RunClock) -> Iterator[None]:
    """Around a run's stepping, timed by ``clock``: a run that stops early carries the samples it kept: a
    DivergenceError its ``trajectory`` and ``finite_trajectory``, Ctrl-C (or SIGTERM under ``pinstab``) an
    :class:`Interrupted` (``info.cut_short`` saying where, cause ``interrupted``), a ContactInfeasibleError or a
    ServoInfeasibleError after t = 0 s its ``trajectory`` (``info.stopped`` naming the failure), a MemoryError
    becomes a MemoryBudgetError with its ``trajectory``. A streamed run's file gets the completed info here, once (a
    run that ends normally gets it from :func:`~pinstab.simulate`); any other failure closes it, removed when it
    holds no row (the target left as it was: :class:`~pinstab.stream.StreamWriter`)."""
    try:
        with clock.stepping_loop():
            yield
    except DivergenceError as exc:
        finite = loop.records.count - 1  # without the failed step's sample
        finite_info = dataclasses.replace(info)
        exc.trajectory = trajectory_of(loop, system, info, clock)
        exc.finite_trajectory = (
            exc.trajectory if _streamed(loop) else trajectory_of(loop, system, finite_info, clock, finite)
        )
        _write_info(exc.trajectory)
        raise
    except KeyboardInterrupt:
        trajectory = trajectory_of(loop, system, info, clock, cut_off=True)
        info.cut_short = {"t": info.t_end, "step": info.steps, "cause": "interrupted"}
        raise Interrupted(_write_info(trajectory)) from None
    except (ContactInfeasibleError, ServoInfeasibleError) as exc:
        if isinstance(exc, ServoInfeasibleError) and exc.time == 0.0:  # the start: refused like `check` does
            raise
        exc.trajectory = trajectory_of(loop, system, info, clock)
        info.stopped = failure_stop(exc, info.t_end)
        _write_info(exc.trajectory)
        raise
    except MemoryError as error:
        trajectory = _write_info(trajectory_of(loop, system, info, clock))
        raise exhausted(f"the run of scene {info.scene}", error, trajectory) from None
    except BaseException:  # any other failure: a stream keeps the rows flushed, or goes when it has none
        if _streamed(loop):
            loop.records.sink.close()
        raise


def _write_info(trajectory: Trajectory | StreamedTrajectory) -> Trajectory | StreamedTrajectory:
    """``trajectory``, its info written to its file when it was streamed."""
    if isinstance(trajectory, StreamedTrajectory):
        trajectory.write_info()
    return trajectory


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


def check_drift_limit(drift_limit: Any) -> float:
    """``drift_limit`` [m or rad] as a float; refused (PinstabError) unless a positive number."""
    if isinstance(drift_limit, bool) or not isinstance(drift_limit, int | float) or not drift_limit > 0:
        raise PinstabError(f"drift_limit must be a positive number, got {drift_limit!r}")
    return float(drift_limit)


def run_memory(scene: Scene, grid: TimeGrid, record_every: int, stream: str | Path | None) -> dict[str, int]:
    """The estimated memory of a run [bytes] by item: its Pinocchio data and its kept samples (a window of them
    when streamed)."""
    model = scene.model
    samples, size = kept_samples(scene, grid.steps if stream is None else STREAM_WINDOW * record_every, record_every)
    return {
        f"Pinocchio data ({RUN_DATA_COPIES} copies, nv = {model.nv})": RUN_DATA_COPIES
        * data_bytes(model.nv, model.njoints),
        f"{samples:,} kept samples": size,
    }


def require_memory(scene: Scene, grid: TimeGrid, record_every: int, stream: str | Path | None) -> None:
    """Refuse (MemoryBudgetError) a run whose :func:`run_memory` would exceed the budget."""
    require(
        run_memory(scene, grid, record_every, stream),
        f"a run of scene {scene.name} ({grid.steps:,} steps, a sample kept every {record_every})",
        "keep fewer samples (--record-every, record_every), stream them to disk (--stream FILE.h5, stream), use a "
        "larger step or a shorter duration",
    )


def stream_records(loop: StepLoop, stream: str | Path | None, info: RunInfo) -> None:
    """With ``stream``, the loop keeps its samples in :class:`StreamedRecords` writing to that file."""
    if stream is None:
        return
    model, rows = loop.system.model, loop.system.model.constraints.rows
    writer = StreamWriter(stream, info, model.nq, model.nv, rows)
    spare = STREAM_WINDOW - BLOCK
    loop.records = StreamedRecords(loop.grid, loop.every, model.nq, model.nv, writer, BLOCK, spare, FLUSH_PERIOD)


def _streamed(loop: StepLoop) -> bool:
    """Whether the loop streams its samples to a file."""
    return isinstance(loop.records, StreamedRecords)


def trajectory_of(
    loop: StepLoop,
    system: ConstrainedSystem,
    info: RunInfo,
    clock: RunClock,
    samples: int | None = None,
    cut_off: bool = False,
) -> Trajectory | StreamedTrajectory:
    """The trajectory of the first ``samples`` samples kept (default: all kept so far), with the run info
    completed and its timings so far (``clock``). A streamed run's file is finished: its last samples written and,
    unless the run was ``cut_off`` (interrupted), its derived series; its info is written by the caller once
    complete (:func:`kept_when_stopped`, :func:`~pinstab.simulate`)."""
    records = loop.records
    n = records.count if samples is None else samples
    info.steps, info.t_end = records.kept(n - 1)
    info.solver_statistics = system.statistics
    info.correction_iterations_total, info.correction_iterations_max = loop.correction_total, loop.correction_max
    info.compiled_steps = 0 if loop.compiled is None else loop.compiled.steps
    watch = getattr(loop, "watch", None)  # none in a run that ended at its start, before stepping
    info.passages = [] if watch is None else [p.to_dict() for p in watch.passages if p.t <= info.t_end]
    events = loop.events if isinstance(loop, EventLoop) else getattr(loop.stepper, "events", None)
    if events is not None:
        info.contact_events = [event.to_dict() for event in events if event.t <= info.t_end]
    if isinstance(loop, AdaptiveLoop):
        info.error_control = loop.control.summary()
    info.newton = loop.newton_figures()
    if _streamed(loop):
        records.finish()
        records.sink.close()
        series = None if cut_off else StateSeries(system)
        streamed = StreamedTrajectory.complete(records.sink.path, info, math.nan, series)
        clock.stamp(streamed)
        return streamed
    flow = SchemeStep(SCHEMES["rk4"], None if system.model.euclidean else system.model.model)
    trajectory = Trajectory(  # views of the samples: no second copy of a long run
        records.t[:n],
        records.q[:n],
        records.v[:n],
        math.nan,
        info,
        correction_iterations=records.corrections[:n],
        series=StateSeries(system, flow),  # the energy balance's flow where the samples do not resolve the power
    )
    clock.stamp(trajectory)
    return trajectory


def run_info(
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


def progress_bar(steps: int, label: str, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=steps, desc=label, unit="step", file=sys.stderr, delay=2.0, mininterval=0.5, leave=False)


def start_state(scene: Scene, q0: np.ndarray | None, v0: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The run's start, as copies: ``q0`` and ``v0`` [rad, m; rad/s, m/s] or the scene's.

    Raises:
        PinstabError: ``q0`` or ``v0`` of the wrong length (naming the lengths the scene's model needs).
        SceneError: an entry of ``v0`` beyond :data:`~pinstab.units.MAX_RATE`, as in ``initial.v``.
    """
    q = scene.q0.copy() if q0 is None else np.asarray(q0, dtype=float).copy()
    v = scene.v0.copy() if v0 is None else np.asarray(v0, dtype=float).copy()
    if q.shape != scene.q0.shape or v.shape != scene.v0.shape:
        raise PinstabError(f"q0 must have {scene.model.nq} entries and v0 {scene.model.nv}")
    check_velocity(scene.model, v, "v0")
    return q, v
