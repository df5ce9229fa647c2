"""The result of a simulation: states, multipliers, drifts, energy, timings; saved as NPZ."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from .errors import PinstabError
from .files import atomic_output
from .runinfo import RunInfo


@dataclass
class Trajectory:
    """A simulated motion, sampled at every step.

    Attributes:
        t: times [s] (n+1,).
        q: configurations (n+1, nq). v: velocities (n+1, nv) [rad/s, m/s].
        multipliers: constraint multipliers (n+1, s) [N, N m]; see ``force_frames``.
        position_drift: max |phi| per sample [m or rad]. velocity_drift: max |g| [m/s or rad/s].
        energy: total mechanical energy [J].
        correction_iterations: post-step projection iterations per sample (projection, post).
        spectral_radius: rho(R(tau W)) of the deviation dynamics per sample (methods with a
            stabilization term; NaN otherwise).
        wall_time: wall-clock time of the stepping loop [s].
        info: scene, method, integrator, solver, step and end time, options, constraint layout,
            assembly report, solver statistics (:class:`~pinstab.runinfo.RunInfo`).
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    multipliers: np.ndarray
    position_drift: np.ndarray
    velocity_drift: np.ndarray
    energy: np.ndarray
    wall_time: float
    info: RunInfo
    correction_iterations: np.ndarray | None = None
    spectral_radius: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.correction_iterations is None:
            self.correction_iterations = np.zeros(len(self.t), dtype=int)
        if self.spectral_radius is None:
            self.spectral_radius = np.full(len(self.t), np.nan)

    @property
    def steps(self) -> int:
        return len(self.t) - 1

    def multipliers_of(self, constraint: str) -> np.ndarray:
        """The multiplier rows of one constraint (n+1, rows), in the frame ``force_frames[name]``."""
        slices = self.info.constraint_rows
        if constraint not in slices:
            raise PinstabError(f"no constraint named {constraint!r}; constraints: {', '.join(slices) or '(none)'}")
        start, stop = slices[constraint]
        return self.multipliers[:, start:stop]

    def summary(self) -> dict[str, Any]:
        """The figures ``pinstab run --json`` prints."""
        finite_energy = self.energy[np.isfinite(self.energy)]
        assembly = self.info.assembly
        statistics = self.info.solver_statistics
        corrections = self.correction_iterations
        radii = self.spectral_radius
        summary = {
            "steps": self.steps,
            "t_end": float(self.t[-1]),
            "wall_s": self.wall_time,
            "max_position_drift": float(np.max(self.position_drift)),
            "max_velocity_drift": float(np.max(self.velocity_drift)),
            "final_position_drift": float(self.position_drift[-1]),
            "final_velocity_drift": float(self.velocity_drift[-1]),
            "energy_start": float(finite_energy[0]) if finite_energy.size else None,
            "energy_end": float(finite_energy[-1]) if finite_energy.size else None,
            "assembly_iterations": None if assembly is None else assembly.iterations,
            "assembly_residual": None if assembly is None else assembly.residual,
            "correction_iterations_total": int(corrections.sum()),
            "correction_iterations_max": int(corrections.max()),
            "solver_fallbacks": statistics.fallbacks,
            "solver_status": statistics.status_counts,
            "solver_worst_residual": max(statistics.worst_primal_residual, statistics.worst_dual_residual),
        }
        if np.any(np.isfinite(radii)):
            summary["max_spectral_radius"] = float(np.nanmax(radii))
        summary["drift_growth_exponent"] = self.drift_growth_exponent()
        return summary

    def drift_growth_exponent(self) -> float | None:
        """p in position drift ~ t^p, fitted (log-log) over the second half of the run; None when the
        drift there is zero or the run is too short. About 2 for an unstabilized run (MATH.md 3)."""
        half = len(self.t) // 2
        t, drift = self.t[half:], self.position_drift[half:]
        keep = (t > 0) & (drift > 0) & np.isfinite(drift)
        if np.count_nonzero(keep) < 10 or np.ptp(np.log(t[keep])) == 0:
            return None
        return float(np.polyfit(np.log(t[keep]), np.log(drift[keep]), 1)[0])

    def save(self, path: str | Path) -> Path:
        """Write an ``.npz`` file atomically (temp file + rename)."""
        with atomic_output(path, ".npz", "trajectory") as temp:
            np.savez_compressed(
                temp,
                t=self.t,
                q=self.q,
                v=self.v,
                multipliers=self.multipliers,
                position_drift=self.position_drift,
                velocity_drift=self.velocity_drift,
                energy=self.energy,
                wall_time=self.wall_time,
                info=json.dumps(self.info.to_dict()),
                correction_iterations=self.correction_iterations,
                spectral_radius=self.spectral_radius,
            )
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        """Read a trajectory written by :meth:`save`."""
        try:
            with np.load(path) as data:
                return cls(
                    t=data["t"],
                    q=data["q"],
                    v=data["v"],
                    multipliers=data["multipliers"],
                    position_drift=data["position_drift"],
                    velocity_drift=data["velocity_drift"],
                    energy=data["energy"],
                    wall_time=float(data["wall_time"]),
                    info=RunInfo.from_dict(json.loads(str(data["info"]))),
                    correction_iterations=data["correction_iterations"],
                    spectral_radius=data["spectral_radius"],
                )
        except (OSError, KeyError, ValueError) as exc:
            raise PinstabError(f"{path}: not a pinstab trajectory file ({exc})") from None


def configurations_at(t: np.ndarray, q: np.ndarray, model: pin.Model, times: np.ndarray) -> np.ndarray:
    """Configurations sampled at ``times`` [s] from samples (t, q), interpolated on the configuration
    group (``pin.interpolate``) and held at the ends."""
    states = []
    last = len(t) - 2
    for time_s in times:
        k = min(max(int(np.searchsorted(t, time_s, side="right")) - 1, 0), max(last, 0))
        if last < 0:
            states.append(q[0].copy())
            continue
        span = t[k + 1] - t[k]
        u = 0.0 if span <= 0 else min(max((time_s - t[k]) / span, 0.0), 1.0)
        states.append(pin.interpolate(model, q[k], q[k + 1], u))
    return np.array(states)
