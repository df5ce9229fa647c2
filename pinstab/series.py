"""Series derived from a run's samples, computed when first asked for (not while stepping): constraint
drift, energy, multipliers and the spectral radius of the deviation dynamics."""

from __future__ import annotations

import math

import numpy as np

from .system import ConstrainedSystem


class StateSeries:
    """Computes a trajectory's derived series from its samples with the system that produced them.

    Args:
        system: the bound system of the run.
    """

    def __init__(self, system: ConstrainedSystem) -> None:
        self.system = system

    def drift_and_energy(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
        """Position drift max |phi| [m or rad], velocity drift max |g| [m/s or rad/s] and total energy
        [J] per sample; NaN at non-finite samples."""
        model = self.system.model
        n = len(t)
        position, velocity, energy = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
        finite = np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)
        for k in np.flatnonzero(finite):
            position[k], velocity[k] = model.violation(q[k], v[k], float(t[k]))  # leaves placements current
            energy[k] = model.energy(q[k], v[k])
        return {"position_drift": position, "velocity_drift": velocity, "energy": energy}

    def multipliers(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The constraint multipliers per sample [N, N m]; NaN at non-finite samples."""
        system = self.system
        out = np.full((len(t), system.model.constraints.rows), np.nan)
        finite = np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)
        with np.errstate(over="ignore", invalid="ignore"):
            for k in np.flatnonzero(finite):
                out[k] = system.multipliers(q[k], v[k], float(t[k]))
        return out

    def spectral_radius(self, t: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """rho(R(tau W)) per sample [-]; NaN for methods without a stabilization term."""
        stabilizer, model = self.system.stabilizer, self.system.model
        if stabilizer.constant_gains:
            radius = stabilizer.spectral_radius(model, q[0], v[0], float(t[0]))
            return np.full(len(t), math.nan if radius is None else radius)
        out = np.full(len(t), np.nan)
        finite = np.isfinite(q).all(axis=1) & np.isfinite(v).all(axis=1)
        for k in np.flatnonzero(finite):
            radius = stabilizer.spectral_radius(model, q[k], v[k], float(t[k]))
            out[k] = math.nan if radius is None else radius
        return out
