"""Stability maps: observed behaviour of a stabilizer over a (step, gain) grid beside the prediction
rho(R(tau W)) = 1 of the discrete criterion (docs/mathematics.md 3.3)."""

from __future__ import annotations

import dataclasses
import math
import sys
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..assembly import perturbed_start
from ..errors import DivergenceError, PinstabError, ProjectionError, UnstableGainsWarning, choices
from ..model import ConstrainedModel
from ..scene import Scene
from ..simulate import simulate
from ..stabilizers import STABILIZERS
from ..system import build_system


def map_methods() -> list[str]:
    """The registered methods a map can sweep: those whose options include gains ``kp`` and ``kd``."""
    return [
        entry.name
        for entry in STABILIZERS.entries()
        if {"kp", "kd"} <= {item.name for item in dataclasses.fields(entry.options)}
    ]


CONVERGED_RATIO = 1e-2  # final / initial position drift at or below this: converged
DIVERGED_RATIO = 1e3  # above this (the runs stop there) or non-finite: diverged; in between: bounded
MAX_GRID = 200  # cells per axis (40 000 runs)
MAX_MAP_STEPS = 20_000_000  # grid^2 x steps: 60 x the default 40 x 40 x 200 (about 1.5 h on the four-bar)
MAX_PERTURBATION = 1.0  # [rad or m]: beyond it the start is far outside the linearization the map checks


@dataclass
class Cell:
    """One (dt, gain) run.

    Attributes:
        dt: step [s]. kp: stiffness gain [1/s^2]. kd: damping gain 2 sqrt(kp) [1/s].
        predicted_radius: rho(R(tau W)) at the start. observed: converged | bounded | diverged.
        drift_ratio: final / initial position drift (inf when the run diverged).
    """

    dt: float
    kp: float
    kd: float
    predicted_radius: float
    observed: str
    drift_ratio: float

    @property
    def predicted_stable(self) -> bool:
        return self.predicted_radius < 1.0

    @property
    def agrees(self) -> bool:
        return self.predicted_stable == (self.observed != "diverged")


@dataclass
class StabilityMap:
    """The grid of cells and how often prediction and observation agree."""

    scene: str
    method: str
    integrator: str
    steps: int
    perturbation: float
    cells: list[Cell] = field(default_factory=list)

    @property
    def agreement(self) -> float:
        """Fraction of cells where rho < 1 coincides with a run that did not diverge."""
        return sum(c.agrees for c in self.cells) / len(self.cells) if self.cells else math.nan

    def to_json(self) -> dict[str, Any]:
        cells = []
        for c in self.cells:
            row = asdict(c)
            row["predicted_stable"] = c.predicted_stable
            row["drift_ratio"] = c.drift_ratio if math.isfinite(c.drift_ratio) else None
            cells.append(row)
        return {
            "scene": self.scene,
            "method": self.method,
            "integrator": self.integrator,
            "steps": self.steps,
            "perturbation": self.perturbation,
            "grid": [len({c.dt for c in self.cells}), len({c.kp for c in self.cells})],
            "agreement": self.agreement,
            "cells": cells,
        }


def stability_map(
    scene: Scene,
    method: str = "baumgarte",
    integrator: str = "semi-implicit-euler",
    dt_range: tuple[float, float] = (1e-4, 3e-2),
    gain_range: tuple[float, float] = (1e2, 1e9),
    grid: int = 40,
    steps: int = 200,
    perturbation: float = 0.01,
    solver: str | None = "dense",
    progress: bool = False,
) -> StabilityMap:
    """Run a grid of short simulations from a start ``perturbation`` [rad] off the manifold.

    Args:
        scene: the scene.
        method: ``baumgarte``, ``pinocchio`` (Kp, Kd) or ``mukharlyamov`` (given kinematic gains
            S = Kp, K = Kd, i.e. H = Kp E, B = Kd E).
        integrator: the integrator.
        dt_range: smallest and largest step [s] (log-spaced).
        gain_range: smallest and largest Kp [1/s^2] (log-spaced); Kd = 2 sqrt(Kp).
        grid: cells per axis (2 to :data:`MAX_GRID`).
        steps: steps per run (at least 2; grid^2 x steps at most :data:`MAX_MAP_STEPS`).
        perturbation: size of the initial violation [rad, tangent norm] (above 0, at most
            :data:`MAX_PERTURBATION`).
        solver: KKT backend for the runs (``dense`` is the fastest on non-redundant scenes).
        progress: progress bar on stderr.

    Raises:
        PinstabError: any argument out of its range, or a scene whose perturbed start violates no
            position constraint. A run that blows up is a ``diverged`` cell; any other error of a run
            (the scene cannot be simulated with these options) is raised.
    """
    _check_map_arguments(method, dt_range, gain_range, grid, steps, perturbation)
    model = ConstrainedModel(scene)
    q_off, v0 = perturbed_start(model, perturbation)
    initial = model.violation(q_off, v0, 0.0).position
    if not initial > 0.0:
        raise PinstabError(
            f"scene {scene.name}: a start {perturbation:g} off the manifold violates no position constraint (its "
            "constraints are velocity-level only); a stability map measures how position errors are repaired, "
            "so it needs holonomic constraints"
        )
    result = StabilityMap(scene.name, method, integrator, steps, perturbation)
    bar = progress_bar(grid * grid, f"stability {scene.name}", progress)
    for dt in np.geomspace(*dt_range, grid):
        for kp in np.geomspace(*gain_range, grid):
            result.cells.append(
                _cell(model, method, integrator, float(dt), float(kp), steps, q_off, v0, initial, solver)
            )
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()
    return result


def _check_map_arguments(
    method: str,
    dt_range: tuple[float, float],
    gain_range: tuple[float, float],
    grid: int,
    steps: int,
    perturbation: float,
) -> None:
    """Refuse a map's arguments out of range (see :func:`stability_map`), naming the argument."""
    if method not in map_methods():
        raise PinstabError(
            f"stability maps take methods with gains kp and kd: {choices(map_methods())}, not {method!r}"
        )
    check_grid({"dt range": dt_range, "gain range": gain_range}, grid, steps, 1)
    if not (isinstance(perturbation, int | float) and 0.0 < perturbation <= MAX_PERTURBATION):
        raise PinstabError(
            f"perturbation must be a number above 0 and at most {MAX_PERTURBATION:g} [rad or m], got {perturbation!r} "
            "(the size of the start's constraint violation; the default is 0.01)"
        )


def check_grid(ranges: dict[str, tuple[float, float]], grid: int, steps: int, panels: int) -> None:
    """Refuse a map's ranges (each two increasing positive finite numbers), its ``grid`` (cells per axis, 2 to
    :data:`MAX_GRID`) and ``steps`` (per run, at least 2) when out of range, or ``panels`` maps of them beyond
    :data:`MAX_MAP_STEPS` steps in all, naming the argument.

    Raises:
        PinstabError: the first argument out of its range.
    """
    for label, (low, high) in ranges.items():
        if not (0 < low < high) or not math.isfinite(high):
            raise PinstabError(f"{label} must be two increasing positive numbers, got {low} {high}")
    for label, value, top in (("grid", grid, MAX_GRID), ("steps", steps, None)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 2 or (top is not None and value > top):
            bounds = "at least 2" if top is None else f"from 2 to {top}"
            raise PinstabError(f"{label} must be a whole number {bounds}, got {value!r}")
    total = panels * grid * grid * steps
    if total > MAX_MAP_STEPS:
        maps = f"{panels} maps" if panels > 1 else "a map"
        raise PinstabError(
            f"{maps} of {grid} x {grid} runs of {steps} steps is {total:,} steps, more than the "
            f"{MAX_MAP_STEPS:,} a map takes (the default 40 x 40 x 200 is 320,000); use a smaller grid or fewer steps"
        )


def progress_bar(total: int, description: str, enabled: bool) -> Any:
    """A progress bar of ``total`` runs on stderr (tqdm), or None when not ``enabled``."""
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=description, unit="run", file=sys.stderr, mininterval=0.5)


def _cell(model: ConstrainedModel, method, integrator, dt, kp, steps, q_off, v0, initial, solver) -> Cell:
    """One map cell: a run from (q_off, v0), whose position violation is ``initial``, at (dt, kp)."""
    kd = 2.0 * math.sqrt(kp)
    system = build_system(model, method, solver, kp=kp, kd=kd)
    system.stabilizer.bind(model, dt, integrator, q_off)
    radius = system.stabilizer.spectral_radius(model, q_off, v0, 0.0)
    scene = model.scene
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableGainsWarning)
        try:
            run = simulate(
                scene,
                method=method,
                integrator=integrator,
                dt=dt,
                duration=steps * dt,
                solver=solver,
                kp=kp,
                kd=kd,
                q0=q_off,
                v0=v0,
                assemble_initial=False,
                drift_limit=DIVERGED_RATIO * initial,
                contacts="held",  # the method's rows, whatever the scene's contacts
            )
        except (DivergenceError, ProjectionError):  # blown up (a failed solve on a blown-up state included)
            return Cell(dt, kp, kd, radius, "diverged", math.inf)
    ratio = float(run.position_drift[-1] / initial)
    observed = "converged" if ratio <= CONVERGED_RATIO else ("bounded" if ratio <= DIVERGED_RATIO else "diverged")
    return Cell(dt, kp, kd, radius, observed, ratio)


def plot_stability_map(result: StabilityMap, path: str | Path) -> Path:
    """Write a PNG: observed classes per cell, the predicted boundary rho = 1 drawn over them."""
    from ..plotting import pyplot, save_figure

    plt = pyplot()
    dts = np.array(sorted({c.dt for c in result.cells}))
    gains = np.array(sorted({c.kp for c in result.cells}))
    codes = {"converged": 0, "bounded": 1, "diverged": 2}
    classes = np.zeros((len(gains), len(dts)))
    radii = np.zeros((len(gains), len(dts)))
    for c in result.cells:
        i, j = int(np.searchsorted(gains, c.kp)), int(np.searchsorted(dts, c.dt))
        classes[i, j] = codes[c.observed]
        radii[i, j] = c.predicted_radius
    fig, ax = plt.subplots(figsize=(7.0, 5.6), dpi=110)
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    colors = ["#4c9a2a", "#e0b43c", "#c0392b"]
    ax.pcolormesh(
        log_edges(dts), log_edges(gains), classes, cmap=ListedColormap(colors), vmin=-0.5, vmax=2.5, shading="flat"
    )
    ax.contour(dts, gains, radii, levels=[1.0], colors="black", linewidths=2.0)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("time step dt [s]")
    ax.set_ylabel("Kp [1/s$^2$]  (Kd = 2$\\sqrt{Kp}$ [1/s])")
    ax.set_title(
        f"{result.scene}: {result.method} + {result.integrator}, {result.steps} steps from "
        f"{result.perturbation:g} rad off\n"
        f"observed vs predicted stability agree on {100 * result.agreement:.1f} % of cells",
        fontsize=10,
    )
    handles = [Patch(color=c, label=name) for c, name in zip(colors, codes, strict=True)]
    handles.append(plt.Line2D([], [], color="black", linewidth=2, label=r"predicted $\rho(R(\tau W)) = 1$"))
    ax.legend(handles=handles, loc="lower left", fontsize=8, framealpha=0.9)
    return save_figure(fig, path)


def log_edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges for log-spaced centres (of a map's axis)."""
    logs = np.log(centres)
    middle = (logs[1:] + logs[:-1]) / 2
    return np.exp(np.concatenate([[2 * logs[0] - middle[0]], middle, [2 * logs[-1] - middle[-1]]]))
