"""The result of a simulation: states, multipliers, drifts, energy, timings; saved as NPZ."""

from __future__ import annotations

import json
import math
import warnings
import zipfile
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pinocchio as pin

from .errors import CutShortWarning, PinstabError, PinstabWarning
from .files import atomic_output
from .runinfo import RunInfo
from .stream import BLOCK, FLUSH_PERIOD, StreamFile, is_stream_file, read_stream, rewrite_info, sample_blocks


class SeriesSource(Protocol):
    """What computes a trajectory's derived series from its samples (:class:`pinstab.series.StateSeries`)."""

    def drift_and_energy(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]: ...

    def multipliers(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray: ...

    def spectral_radius(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray: ...

    def contact_figures(
        self, t: np.ndarray, q: np.ndarray, v: np.ndarray, multipliers: Callable[[], np.ndarray]
    ) -> dict[str, Any]: ...

    def force_figures(
        self, t: np.ndarray, q: np.ndarray, v: np.ndarray, multipliers: Callable[[], np.ndarray]
    ) -> dict[str, Any]: ...

    def servo_figures(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> dict[str, Any]: ...

    def zero_dynamics(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> dict[str, Any]: ...
    def energy_balance(
        self, t: np.ndarray, q: np.ndarray, v: np.ndarray, energy: np.ndarray, events: bool = False
    ) -> dict[str, float]: ...


@dataclass
class Comparison:
    """The trajectory error of a run against a reference (:func:`pinstab.trajectory_error`).

    Attributes:
        reference: what the run was compared with, in words.
        names: the coordinates compared (joint or frame names, or ``joints``). units: theirs (rad, m).
        error: (n, k) the error of each coordinate at each of the run's samples [rad or m].
    """

    reference: str
    names: list[str]
    units: list[str]
    error: np.ndarray

    def summary(self, t: np.ndarray) -> dict[str, Any]:
        """The JSON block: per coordinate the largest error, its time [s] and the final error; the largest."""
        coordinates = {}
        for name, unit, column in zip(self.names, self.units, self.error.T, strict=True):
            finite = np.where(np.isfinite(column), column, -np.inf)
            worst = int(np.argmax(finite))
            coordinates[name] = {
                "max": float(column[worst]),
                "at": float(t[worst]),
                "final": float(column[-1]),
                "unit": unit,
            }
        largest = max((entry["max"] for entry in coordinates.values()), default=None)
        return {"reference": self.reference, "max": largest, "coordinates": coordinates}

    def to_json(self) -> str:
        return json.dumps({"reference": self.reference, "names": self.names, "units": self.units})

    @classmethod
    def from_arrays(cls, text: str, error: np.ndarray) -> Comparison:
        fields = json.loads(text)
        return cls(fields["reference"], list(fields["names"]), list(fields["units"]), error)


class Trajectory:
    """A simulated motion, sampled every ``info.record_every`` steps and at the last.

    The states are stored while stepping; the derived series (drift, energy, multipliers, spectral
    radius) are computed from them when first read (``series``), or given (a loaded file).

    Attributes:
        t: times [s] (n,). q: configurations (n, nq). v: velocities (n, nv) [rad/s, m/s].
        multipliers: constraint multipliers (n, s) [N, N m]; see ``info.force_frames``.
        position_drift: max ``|phi|`` per sample [m or rad]. velocity_drift: max ``|g|`` [m/s or rad/s].
        energy: total mechanical energy [J].
        correction_iterations: post-step projection iterations of each sampled step (projection, post).
        spectral_radius: rho(R(tau W)) of the deviation dynamics per sample (methods with a
            stabilization term; NaN otherwise).
        wall_time: wall-clock time of the :func:`~pinstab.simulate` call [s]: set-up, stepping and post-processing
            (``info.timings`` splits it; a file saved without ``info.timings`` holds the stepping loop's alone).
        info: scene, method, integrator, solver, path, step and end time, options, constraint layout,
            assembly report, solver statistics (:class:`~pinstab.runinfo.RunInfo`).
        comparison: the trajectory error against a reference, when one was computed (saved with the run).
    """

    DERIVED = ("multipliers", "position_drift", "velocity_drift", "energy", "spectral_radius")

    def __init__(
        self,
        t: np.ndarray,
        q: np.ndarray,
        v: np.ndarray,
        wall_time: float,
        info: RunInfo,
        *,
        correction_iterations: np.ndarray | None = None,
        series: SeriesSource | None = None,
        **derived: np.ndarray,
    ) -> None:
        unknown = sorted(set(derived) - set(self.DERIVED))
        if unknown:
            raise PinstabError(f"unknown trajectory series {unknown[0]!r}; series: {', '.join(self.DERIVED)}")
        self.t, self.q, self.v = t, q, v
        self.wall_time, self.info = wall_time, info
        self.correction_iterations = (
            np.zeros(len(t), dtype=int) if correction_iterations is None else correction_iterations
        )
        self._series = series
        self.comparison: Comparison | None = None
        self._derived: dict[str, np.ndarray] = dict(derived)
        if series is None:
            missing = [name for name in self.DERIVED if name not in derived and name != "spectral_radius"]
            if missing:
                raise PinstabError(f"a trajectory without its system needs the series {', '.join(missing)}")
            self._derived.setdefault("spectral_radius", np.full(len(t), np.nan))

    def _get(self, name: str) -> np.ndarray:
        if name not in self._derived:
            series = self._series
            if name == "multipliers":
                self._derived[name] = series.multipliers(self.t, self.q, self.v)
            elif name == "spectral_radius":
                self._derived[name] = series.spectral_radius(self.t, self.q, self.v)
            else:
                self._derived.update(series.drift_and_energy(self.t, self.q, self.v))
        return self._derived[name]

    def compute_series(self) -> None:
        """Compute the drift and energy series now (else they are computed when first read)."""
        self._get("energy")

    multipliers = property(lambda self: self._get("multipliers"), doc="(n, s) [N, N m]")
    position_drift = property(lambda self: self._get("position_drift"), doc="(n,) [m or rad]")
    velocity_drift = property(lambda self: self._get("velocity_drift"), doc="(n,) [m/s or rad/s]")
    energy = property(lambda self: self._get("energy"), doc="(n,) [J]")
    spectral_radius = property(lambda self: self._get("spectral_radius"), doc="(n,) [-]")

    @property
    def steps(self) -> int:
        """Steps taken (the samples may be fewer: see ``info.record_every``)."""
        return self.info.steps

    def multipliers_of(self, constraint: str) -> np.ndarray:
        """The multiplier rows of one constraint (n+1, rows), in the frame ``force_frames[name]``."""
        slices = self.info.constraint_rows
        if constraint not in slices:
            raise PinstabError(f"no constraint named {constraint!r}; constraints: {', '.join(slices) or '(none)'}")
        start, stop = slices[constraint]
        return self.multipliers[:, start:stop]

    def summary(self) -> dict[str, Any]:
        """The figures ``pinstab run --json`` prints; maxima over the finite samples (None when none is)."""
        figures = SeriesFigures(len(self.t))
        figures.add(self.t, self.position_drift, self.velocity_drift, self.energy, self.spectral_radius)
        summary = run_figures(self.info, self.wall_time, float(self.t[-1]), figures.result())
        if self._series is not None:
            summary.update(self._series.contact_figures(self.t, self.q, self.v, lambda: self.multipliers))
            events = bool(self.info.contact_events)
            summary.update(self._series.energy_balance(self.t, self.q, self.v, self.energy, events))
            summary.update(self._series.force_figures(self.t, self.q, self.v, lambda: self.multipliers))
            servo = self.servo_figures
            if servo:
                names = self.info.controls
                summary["max_servo_error"] = float(np.nanmax(servo["servo_error"]))
                summary["controls"] = {
                    name: {"max_abs": float(np.nanmax(np.abs(column))), "final": float(column[-1])}
                    for name, column in zip(names, servo["controls"].T, strict=True)
                }
                summary["zero_dynamics"] = self.zero_dynamics
        return summary

    @property
    def servo_figures(self) -> dict[str, np.ndarray]:
        """With prescribed constraints: ``controls`` (n, k) [N m or N] (names in ``info.controls``) and
        ``servo_error`` (n,), the largest prescribed residual [m or rad]; computed when first read."""
        if "servo" not in self._derived:
            self._derived["servo"] = {} if self._series is None else self._series.servo_figures(self.t, self.q, self.v)
        return self._derived["servo"]

    @property
    def zero_dynamics(self) -> dict[str, Any]:
        """With prescribed constraints: the coordinates they leave free, the eigenvalues [1/s] of the zero
        dynamics linearized at the start and each free coordinate's speeds [rad/s or m/s] (whether it ran away:
        :func:`pinstab.zero_dynamics.zero_dynamics_report`); empty otherwise or for a loaded run."""
        if "zero_dynamics" not in self._derived:
            series = self._series
            self._derived["zero_dynamics"] = {} if series is None else series.zero_dynamics(self.t, self.q, self.v)
        return self._derived["zero_dynamics"]

    def drift_growth_exponent(self) -> float | None:
        """p in position drift ~ t^p, fitted (log-log) over the second half of the run; None when the
        drift there is zero or the run is too short. About 2 for an unstabilized run (docs/mathematics.md 3)."""
        figures = SeriesFigures(len(self.t))
        figures.add(self.t, self.position_drift, self.velocity_drift, self.energy, self.spectral_radius)
        return figures.growth_exponent()

    def save(self, path: str | Path) -> Path:
        """Write an ``.npz`` file atomically (temp file + rename)."""
        arrays = {name: getattr(self, name) for name in SAVED_ARRAYS if name != "info"}
        if self.comparison is not None:
            arrays.update(comparison=self.comparison.to_json(), comparison_error=self.comparison.error)
        with atomic_output(path, ".npz", "trajectory") as temp:
            np.savez_compressed(temp, info=json.dumps(self.info.to_dict()), **arrays)
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        """Read a trajectory written by :meth:`save` (``.npz``) or streamed (``.h5``, :mod:`pinstab.stream`: a run
        cut short holds its samples so far, its derived series NaN, ``info.cut_short`` and a CutShortWarning saying so).

        Raises:
            PinstabError: the file is missing, truncated or damaged, not an NPZ or HDF5 run file, or one whose
                arrays do not describe a run (named: the missing array, the one whose shape does not fit, the first
                sample whose time or state is not finite, times that go back).
        """
        if Path(path).is_dir():
            raise PinstabError(f"{path} is a folder, not a pinstab trajectory file (.npz, .h5)")
        if not Path(path).exists():
            raise PinstabError(f"{path}: the trajectory file does not exist")
        if is_stream_file(path):
            return cls._load_stream(path)
        if not zipfile.is_zipfile(path):
            raise PinstabError(
                f"{path}: not a pinstab trajectory file (not an NPZ archive, or a truncated one; a run is read from "
                "the .npz of --save or the .h5 of --stream)"
            )
        try:
            with np.load(path) as data:
                missing = [name for name in SAVED_ARRAYS if name not in data.files]
                if missing:
                    raise PinstabError(
                        f"{path}: not a pinstab trajectory file (no {', '.join(missing)}; it holds "
                        f"{', '.join(data.files) or 'nothing'})"
                    )
                arrays = {name: data[name] for name in SAVED_ARRAYS}
                info = RunInfo.from_json(str(arrays.pop("info")), str(path))
                comparison = (
                    Comparison.from_arrays(str(data["comparison"]), data["comparison_error"])
                    if "comparison" in data.files
                    else None
                )
        except PinstabError:
            raise
        except (OSError, KeyError, ValueError, TypeError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
            raise PinstabError(f"{path}: not a readable pinstab trajectory file ({exc})") from None
        if comparison is not None and comparison.error.shape != (arrays["t"].size, len(comparison.names)):
            raise PinstabError(f"{path}: the trajectory error's shape {comparison.error.shape} does not fit the run")
        n = _checked_samples(path, arrays)
        wall_time = float(arrays.pop("wall_time"))
        arrays = {name: array[:n] for name, array in arrays.items()}
        if comparison is not None:
            comparison.error = comparison.error[:n]
        if info.cut_short is not None:  # a run interrupted with --save, or a stream cut short saved again
            _warn_cut_short(path, info.cut_short, "the file holds its samples up to there", stacklevel=3)
        trajectory = cls(info=info, wall_time=wall_time, **arrays)
        trajectory.comparison = comparison
        return trajectory

    @classmethod
    def _load_stream(cls, path: str | Path) -> Trajectory:
        """The trajectory of a streamed run file, read whole; a run cut short is marked (``info.cut_short``) and
        warned of (:class:`~pinstab.errors.CutShortWarning`)."""
        arrays, info, wall_time, complete = read_stream(path)
        steps = arrays.pop("step")
        if not len(arrays["t"]):
            raise PinstabError(
                f"{path}: the streamed run holds no sample yet (its rows are written every {BLOCK} samples or "
                f"{FLUSH_PERIOD:g} s: a run's file before its first write, a temporary file renamed onto its target "
                "with its first rows)"
            )
        n = _checked_samples(path, {"wall_time": np.asarray(wall_time), "step": steps, **arrays})
        if not complete:
            _mark_cut_short(path, info, float(arrays["t"][-1]), int(steps[-1]), wall_time)
        return cls(info=info, wall_time=wall_time, **{name: array[:n] for name, array in arrays.items()})


def _mark_cut_short(path: str | Path, info: RunInfo, t: float, step: int, wall_time: float) -> None:
    """Mark the info of a streamed run cut short at its last sample (t [s], ``step``): ``info.cut_short``, and the
    end time and steps of a killed run's info (its start's); warn of it (CutShortWarning). A wall time [s] written
    (finite) means the run's final info was written: it was interrupted (Ctrl-C, SIGTERM), not killed."""
    interrupted = math.isfinite(wall_time)
    info.cut_short = {"t": t, "step": step, "cause": "interrupted" if interrupted else "killed"}
    info.t_end, info.steps = t, step
    derived = ", ".join(Trajectory.DERIVED)
    held = f"its samples up to there are read, its derived series ({derived}) were not written: NaN"
    _warn_cut_short(path, info.cut_short, held, stacklevel=5)


def _warn_cut_short(path: str | Path, cut_short: dict[str, Any], held: str, stacklevel: int) -> None:
    """Warn (CutShortWarning, ``stacklevel`` as :func:`warnings.warn`'s, counted from here) that the run of file
    ``path`` was cut short (``info.cut_short``: t [s], step, cause), then what the file ``held``."""
    how = (
        "interrupted (Ctrl-C or SIGTERM)"
        if cut_short.get("cause") == "interrupted"
        else "killed (kill -9, a crash or a power cut; the rows flushed before, its info as at its start)"
    )
    t = cut_short.get("t")
    when = f"{t:.9g}" if isinstance(t, int | float) else repr(t)  # a number, unless the file was edited
    where = f"t = {when} s (step {cut_short.get('step')})"
    warnings.warn(CutShortWarning(f"{path}: the run was cut short at {where}: {how}; {held}"), stacklevel=stacklevel)


class SeriesFigures:
    """The summary figures of a run's series, accumulated block by block over its n samples (a run streamed to
    disk is never read whole).

    Args:
        n: the run's samples (the drift growth is fitted over the second half).
    """

    def __init__(self, n: int) -> None:
        self.half, self.seen = n // 2, 0
        self.position, self.velocity = _Extreme(), _Extreme()
        self.energy_start = self.energy_end = self.radius = None
        self.final = (float("nan"), float("nan"))
        self.fit = np.zeros(5)  # over the second half, x = log t, y = log drift: count, sum x, sum y, xx, xy
        self.span = (np.inf, -np.inf)  # the smallest and largest x

    def add(
        self, t: np.ndarray, position: np.ndarray, velocity: np.ndarray, energy: np.ndarray, radius: np.ndarray
    ) -> None:
        """The next block: times [s], position drift [m or rad], velocity drift [m/s or rad/s], energy [J],
        spectral radius [-]."""
        self.position.add(position)
        self.velocity.add(velocity)
        finite = energy[np.isfinite(energy)]
        if finite.size:
            self.energy_start = float(finite[0]) if self.energy_start is None else self.energy_start
            self.energy_end = float(finite[-1])
        if np.any(np.isfinite(radius)):
            self.radius = max(float(np.nanmax(radius)), -np.inf if self.radius is None else self.radius)
        if len(t):
            self.final = (float(position[-1]), float(velocity[-1]))
        late = slice(max(self.half - self.seen, 0), None)
        t_late, drift = t[late], position[late]
        keep = (t_late > 0) & (drift > 0) & np.isfinite(drift)
        x, y = np.log(t_late[keep]), np.log(drift[keep])
        self.fit += (x.size, x.sum(), y.sum(), x @ x, x @ y)
        if x.size:
            self.span = (min(self.span[0], x.min()), max(self.span[1], x.max()))
        self.seen += len(t)

    def growth_exponent(self) -> float | None:
        """p in position drift ~ t^p, the least-squares slope of log drift on log t over the second half; None
        with fewer than 10 positive drifts there or a single time."""
        count, sx, sy, sxx, sxy = self.fit
        if count < 10 or self.span[1] - self.span[0] == 0:
            return None
        return float((count * sxy - sx * sy) / (count * sxx - sx * sx))

    def result(self) -> dict[str, Any]:
        """The figures of :func:`run_figures`."""
        figures = {
            "max_position_drift": self.position.largest,
            "max_velocity_drift": self.velocity.largest,
            "final_position_drift": self.final[0],
            "final_velocity_drift": self.final[1],
            "energy_start": self.energy_start,
            "energy_end": self.energy_end,
        }
        if self.radius is not None:
            figures["max_spectral_radius"] = self.radius
        figures["drift_growth_exponent"] = self.growth_exponent()
        return figures


class _Extreme:
    """The largest finite value seen (None when none was)."""

    def __init__(self) -> None:
        self.largest: float | None = None

    def add(self, values: np.ndarray) -> None:
        block = _finite_max(values)
        if block is not None:
            self.largest = block if self.largest is None else max(self.largest, block)


def run_figures(info: RunInfo, wall_time: float, t_end: float, figures: dict[str, Any]) -> dict[str, Any]:
    """The summary of a run (:meth:`Trajectory.summary` without the scene's own figures): its info, wall time
    [s], end time [s] and series ``figures`` (:meth:`SeriesFigures.result`)."""
    assembly = info.assembly
    statistics = info.solver_statistics
    radius = figures.pop("max_spectral_radius", None)
    growth = figures.pop("drift_growth_exponent")
    summary = {
        "steps": info.steps,
        "t_end": t_end,
        "wall_s": wall_time,
        "timings": info.timings,
        **figures,
        "assembly_iterations": None if assembly is None else assembly.iterations,
        "assembly_residual": None if assembly is None else assembly.residual,
        "assembly_tolerance": None if assembly is None else assembly.tolerance,
        "correction_iterations_total": info.correction_iterations_total,
        "correction_iterations_max": info.correction_iterations_max,
        "solver_fallbacks": statistics.fallbacks,
        "solver_status": statistics.status_counts,
        "solver_worst_residual": max(statistics.worst_primal_residual, statistics.worst_dual_residual),
    }
    if radius is not None:
        summary["max_spectral_radius"] = radius
    summary["drift_growth_exponent"] = growth
    summary["dynamics_evaluations"] = statistics.solves
    if info.error_control is not None:
        summary["error_control"] = info.error_control
    if info.newton is not None:
        summary["newton"] = info.newton
    passages = info.passages
    summary["singular_passages"] = passages
    summary["branch_changes"] = sum(not passage["branch_kept"] for passage in passages)
    summary["contact_events"] = info.contact_events
    summary["stopped"] = info.stopped
    if info.limits_active_s is not None:
        summary["limits_active_s"] = info.limits_active_s
    if info.cut_short is not None:
        summary["cut_short"] = info.cut_short
    return summary


class StreamedTrajectory:
    """A run streamed to an HDF5 file (:mod:`pinstab.stream`): its info and summary, its samples on disk.

    Attributes:
        path: the file. info: the run info. wall_time: the wall time of the :func:`~pinstab.simulate` call [s]
            (``info.timings`` splits it).
        figures: the summary's figures (:meth:`summary`); None for a run cut off (interrupted).
    """

    def __init__(self, path: Path, info: RunInfo, wall_time: float, figures: dict[str, Any] | None) -> None:
        self.path, self.info, self.wall_time, self.figures = path, info, wall_time, figures

    @classmethod
    def complete(
        cls, path: str | Path, info: RunInfo, wall_time: float, series: SeriesSource | None
    ) -> StreamedTrajectory:
        """Finish a streamed file: its derived series computed block by block from its samples with ``series``
        (None: a run cut short, left without them) and its summary written; :meth:`write_info` then writes the final
        info and marks the file complete (the info is written once at the end, not once more here)."""
        file = StreamFile(path)
        figures = None
        if series is not None:
            accumulated = SeriesFigures(file.size)
            for start, t, q, v in file.blocks():
                derived = series.drift_and_energy(t, q, v)
                derived["spectral_radius"] = series.spectral_radius(t, q, v)
                derived["multipliers"] = series.multipliers(t, q, v)
                file.write_series(start, derived)
                accumulated.add(t, derived["position_drift"], derived["velocity_drift"], derived["energy"],
                                derived["spectral_radius"])  # fmt: skip
            figures = accumulated.result()
        file.finish(figures)
        return cls(Path(path), info, wall_time, figures)

    @property
    def steps(self) -> int:
        """Steps taken."""
        return self.info.steps

    def summary(self) -> dict[str, Any]:
        """The figures ``pinstab run --json`` prints (:func:`run_figures`, with ``stream``: the file); those a
        scene's contacts, force elements and servos add to a run kept in memory are left to :meth:`load`."""
        figures = dict(self.figures) if self.figures is not None else dict.fromkeys(SeriesFigures(0).result())
        return {**run_figures(self.info, self.wall_time, self.info.t_end, figures), "stream": str(self.path)}

    def write_info(self) -> None:
        """Write :attr:`info` and :attr:`wall_time` to the file (after the run's end completed them: limits, stop,
        timings), marking it complete when its derived series are written."""
        rewrite_info(self.path, self.info, self.wall_time, self.figures is not None)

    def blocks(self) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """(t [s], q) of the file's samples, a block at a time."""
        return sample_blocks(self.path)

    def load(self) -> Trajectory:
        """The run read whole from its file (:meth:`Trajectory.load`)."""
        return Trajectory.load(self.path)


SAVED_ARRAYS = (  # what save() writes and load() requires: the attributes of these names, ``info`` as JSON
    "t",
    "q",
    "v",
    "multipliers",
    "position_drift",
    "velocity_drift",
    "energy",
    "wall_time",
    "info",
    "correction_iterations",
    "spectral_radius",
)


def _checked_samples(path: str | Path, arrays: dict[str, np.ndarray]) -> int:
    """Refuse a file whose arrays do not describe one run: n >= 1 finite increasing sample times [s], every series
    with n rows of numbers, finite states. Returns the samples to read: n, or n - 1 when the last state alone is not
    finite, a diverged run's failed step (a stream keeps it, ``--save`` leaves it out), left out with a warning."""
    t = arrays["t"]
    if t.ndim != 1 or t.size == 0 or t.dtype.kind not in "fi":
        raise PinstabError(f"{path}: 't' must be a non-empty list of sample times, got shape {t.shape} of {t.dtype}")
    for name, array in arrays.items():
        if name == "wall_time":
            ok = array.shape == () and array.dtype.kind in "fi"
        else:
            ok = array.dtype.kind in "fi" and array.ndim == (2 if name in ("q", "v", "multipliers") else 1)
            ok = ok and array.shape[0] == t.size
        if not ok:
            raise PinstabError(
                f"{path}: array {name!r} (shape {array.shape}, {array.dtype}) does not fit {t.size} samples"
            )
    failed = t.size > 1 and not (np.isfinite(arrays["q"][-1]).all() and np.isfinite(arrays["v"][-1]).all())
    n = t.size - failed
    for name in ("t", "q", "v"):
        finite = np.isfinite(arrays[name][: t.size if name == "t" else n])
        bad = ~(finite if finite.ndim == 1 else finite.all(axis=1))
        if bad.any():
            first = int(np.argmax(bad))
            when = "" if name == "t" else f" (t = {t[first]:.9g} s)"
            raise PinstabError(
                f"{path}: array {name!r} is not finite at sample {first} of {t.size}{when}: a damaged file"
            )
    backwards = np.diff(t) < 0
    if backwards.any():
        first = int(np.argmax(backwards)) + 1
        raise PinstabError(
            f"{path}: the sample times 't' must increase; sample {first} (t = {t[first]:.9g} s) is before the one "
            f"before it (t = {t[first - 1]:.9g} s)"
        )
    if failed:
        warnings.warn(
            PinstabWarning(
                f"{path}: the state of the last sample (t = {t[-1]:.9g} s) is not finite, the failed step of a run "
                f"that diverged: read up to the sample before (t = {t[-2]:.9g} s), as --save keeps a diverged run"
            ),
            stacklevel=4,
        )
    return n


def _finite_max(values: np.ndarray) -> float | None:
    """The largest finite entry of ``values``, or None when there is none."""
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else None


def sample_weights(t: np.ndarray, time_s: float) -> tuple[int, float]:
    """(k, u): the time ``time_s`` [s] lies a fraction u in [0, 1] of the way from sample k to k + 1 of the
    increasing sample times ``t`` [s] (held at the ends; k = 0, u = 0 for a single sample)."""
    if len(t) < 2:
        return 0, 0.0
    k = min(max(int(np.searchsorted(t, time_s, side="right")) - 1, 0), len(t) - 2)
    span = t[k + 1] - t[k]
    return k, 0.0 if span <= 0 else min(max((time_s - t[k]) / span, 0.0), 1.0)


def configurations_at(t: np.ndarray, q: np.ndarray, model: pin.Model, times: np.ndarray) -> np.ndarray:
    """Configurations sampled at ``times`` [s] from samples (t, q), interpolated on the configuration
    group (``pin.interpolate``) and held at the ends."""
    if len(t) < 2:
        return np.array([q[0].copy() for _ in times])
    return np.array([pin.interpolate(model, q[k], q[k + 1], u) for k, u in (sample_weights(t, x) for x in times)])
