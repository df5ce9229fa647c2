"""Stability maps of a stiff force element: observed behaviour of integrators over a (step, element scale) grid beside
the prediction from the linearized motion's eigenvalues and each scheme's stability function (issue 37).

A scene whose force element makes the motion stiff (``stiff-fourbar``'s spring-damper) has no gains to sweep: the
map's second axis scales the element. By default its stiffness and damping together (``scale="element"``): the
force law times a factor s. An overdamped element's fast eigenvalue is about ``-c / m`` (damping-dominated:
``stiff-fourbar``'s damping ratio is 9.5, its fast eigenvalue -7159 /s beside -c / m = -7184 /s), so the stiffness
alone moves it little until the element is critically damped (s ~ 90 there); scaled together the fast eigenvalue
moves as s and the slow relaxation -k / c stays. ``scale="stiffness"`` scales k alone.

Each cell is a run of ``steps`` steps from the scene's start. The mechanism is passive (springs, dampers, gravity:
its energy E = T + V never grows), so the energy a run gains is the step's: its ratio
``sqrt(max(E - E0) / E_scale)`` (E_scale the kinetic and element energy at the start: a speed ratio) classes it
``dissipative`` (at most :data:`~pinstab.analysis.stability_map.CONVERGED_RATIO`), ``bounded`` or ``diverged``
(above :data:`~pinstab.analysis.stability_map.DIVERGED_RATIO`, or blown up); an implicit scheme's run whose stage
equation Newton's iteration cannot solve (:class:`~pinstab.errors.NewtonError`, no root on the motion's branch at
that step) is ``unsolved``, neither stable nor diverged: it counts against a prediction of stability.

Predicted from the linearization at the start: one step multiplies each mode by ``|R(h lambda)|``
(:func:`pinstab.stability.criterion.step_growth`; beyond the motion's own growth for a mode that grows on its own). The
scheme's region, ``|R| <= 1`` on every mode, is the asymptotic prediction; a run of N steps diverges when a mode grows
by more than the diverged ratio over them: ``excess^N > DIVERGED_RATIO``. That is the prediction compared with the
runs (``agreement``): a lightly damped mode (``stiff-fourbar``'s motion across its spring, stiffened by the spring's
initial tension, -1.3 +- 141i /s) is outside explicit Euler's region at any step, yet grows by less than 1.04 per
step below 2 ms and has died out (the tension relaxes at k / c = 20 /s) long before it could show; the region's own
agreement is reported beside it (``region_agreement``). The start, not states along a run: near a stiff mode's limit
the runs last N x 2.8 / |lambda| (0.08 s at the base stiffness for RK4, 200 steps), over which the eigenvalues move
little.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DivergenceError, NewtonError, PinstabError, ProjectionError, UnstableGainsWarning, choices
from ..integration import INTEGRATORS
from ..model import ConstrainedModel, kinetic_energy
from ..scene import Scene, scene_from_dict
from ..simulate import simulate
from ..stability.criterion import mode_step_limit, schemes, step_growth
from ..stability.modes import StiffMode, linearize, stiffest_mode
from ..validation import read_scene_file
from .stability_map import CONVERGED_RATIO, DIVERGED_RATIO, check_grid, log_edges, progress_bar

SCALES = ("element", "stiffness")  # what the factor multiplies: stiffness and damping together, or the stiffness
CLASSES = ("dissipative", "bounded", "diverged", "unsolved")
RAN = ("dissipative", "bounded")  # the classes of a run that did not diverge
PANELS_PER_ROW = 4  # the most panels in a row of the figure


def map_integrators() -> list[str]:
    """The registered integrators an element map can run: those whose growth per step is known
    (:func:`pinstab.stability.criterion.schemes`)."""
    return [name for name in schemes() if name in INTEGRATORS]


def stiff_elements(scene: Scene) -> list[str]:
    """The scene's force elements a map can scale: those with a stiffness."""
    return [element.name for element in scene.forces if hasattr(element, "stiffness")]


def default_element(scene: Scene) -> str | None:
    """The element a map scales when none is named: on a scene without constraints (no gains to sweep) with force
    elements that have a stiffness, the one that owns the stiffest mode at the start (the only one, when one); None
    on a scene with constraints or without such elements (its map is the stabilizer's gains).

    Raises:
        PinstabError: several such elements and none owns the stiffest mode (naming them).
    """
    elements = stiff_elements(scene)
    if scene.constraints or not elements:
        return None
    if len(elements) == 1:
        return elements[0]
    mode = stiffest_mode(ConstrainedModel(scene), scene.q0, scene.v0, 0.0)
    if mode is not None and mode.element in elements:
        return mode.element
    raise PinstabError(
        f"scene {scene.name} has no constraints (no gains to map) and no force element owns its stiffest mode: "
        f"name the element to map with --element, one of {choices(elements)}"
    )


@dataclass
class ElementCell:
    """One (integrator, dt, factor) run.

    Attributes:
        integrator: the scheme. dt: step [s]. factor: the element's scale [-].
        excess: the largest growth per step of a mode beyond the motion's own, from the start's linearization [-].
        observed: dissipative | bounded | diverged | unsolved. energy_ratio: the energy gained, as a speed ratio
        (inf: blown up or unsolved). steps: the run's steps.
    """

    integrator: str
    dt: float
    factor: float
    excess: float
    observed: str
    energy_ratio: float
    steps: int

    @property
    def predicted_stable(self) -> bool:
        """No mode grows by more than the diverged ratio over the run's steps."""
        return self.steps * math.log(max(self.excess, 1e-300)) <= math.log(DIVERGED_RATIO)  # nan: not stable

    @property
    def in_region(self) -> bool:
        """Every mode's step inside the scheme's region (|R| <= 1 beyond the motion's own growth)."""
        return self.excess <= 1.0


@dataclass
class ElementMap:
    """The cells of every integrator, the stiffest mode at the base scale and each scheme's limit on it."""

    scene: str
    element: str
    scale: str
    steps: int
    integrators: list[str]
    mode: StiffMode | None
    limits: dict[str, float]
    cells: list[ElementCell] = field(default_factory=list)

    def agreement(self, integrator: str, region: bool = False) -> float:
        """Fraction of ``integrator``'s cells where the prediction (``region``: |R| <= 1 on every mode) coincides
        with a run that did not diverge."""
        own = [c for c in self.cells if c.integrator == integrator]
        agrees = [(c.in_region if region else c.predicted_stable) == (c.observed in RAN) for c in own]
        return sum(agrees) / len(agrees) if agrees else math.nan

    def criterion(self) -> str:
        """The stiff mode that limits an explicit step, in words: its element, frequency and eigenvalue at the base
        scale, and each scheme's largest step inside its region for it."""
        mode = self.mode
        if mode is None or not mode.decays:
            return f"scene {self.scene}: no decaying stiffest mode at the start (no step limit from it)"
        owner = f"belongs to force element {mode.element!r}" if mode.element else "belongs to no single force element"
        limits = ", ".join(
            f"{name} {1e3 * limit:.3g} ms" if math.isfinite(limit) else f"{name} none (A-stable)"
            for name, limit in self.limits.items()
        )
        value = mode.eigenvalue
        eigenvalue = f"{value.real:.4g}" if value.imag == 0 else f"{value.real:.4g} {value.imag:+.4g}i"
        frequency = f"{mode.frequency:.4g} rad/s, " if math.isfinite(mode.frequency) else ""
        return (
            f"the stiffest mode at the base scale {owner} ({frequency}lambda = {eigenvalue} /s); the largest step "
            f"that keeps it in each scheme's region: {limits}"
        )

    def to_json(self, cells: bool = True) -> dict[str, Any]:
        """The map as JSON: per scheme its agreement and counts; the stiffest mode and its limits; the cells."""
        schemes = {}
        for name in self.integrators:
            own = [c for c in self.cells if c.integrator == name]
            schemes[name] = {
                "agreement": self.agreement(name),
                "region_agreement": self.agreement(name, region=True),
                "limit_dt": _finite(self.limits[name]),
            } | {label: sum(c.observed == label for c in own) for label in CLASSES}
        mode = None
        if self.mode is not None:
            mode = {
                "element": self.mode.element,
                "frequency": _finite(self.mode.frequency),
                "eigenvalue": [self.mode.eigenvalue.real, self.mode.eigenvalue.imag],
                "stiffness": self.mode.stiffness,
                "damping": self.mode.damping,
            }
        payload = {
            "scene": self.scene,
            "criterion": self.criterion(),
            "kind": "element",
            "element": self.element,
            "scale": self.scale,
            "steps": self.steps,
            "grid": [len({c.dt for c in self.cells}), len({c.factor for c in self.cells})],
            "stiffest_mode": mode,
            "schemes": schemes,
        }
        if cells:
            payload["cells"] = [
                {
                    "integrator": c.integrator,
                    "dt": c.dt,
                    "factor": c.factor,
                    "excess": _finite(c.excess),
                    "predicted_stable": c.predicted_stable,
                    "in_region": c.in_region,
                    "observed": c.observed,
                    "energy_ratio": _finite(c.energy_ratio),
                }
                for c in self.cells
            ]
        return payload


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def scaled_scene(scene: Scene, element: str, factor: float, scale: str = "element") -> Scene:
    """``scene`` read again from its file with force element ``element``'s stiffness (``scale="element"``: and its
    damping) times ``factor`` [-], through the scene's own force table (the file is not changed).

    Raises:
        PinstabError: an element that is not one of the scene file's ``[[forces]]`` with a stiffness, or a scene
            built without a file.
    """
    elements = stiff_elements(scene)
    if element not in elements:
        raise PinstabError(
            f"scene {scene.name} has no force element {element!r} with a stiffness; elements with one: "
            f"{choices(elements) if elements else '(none)'}"
        )
    data = read_scene_file(scene.source) if scene.source is not None else {}
    entries = [entry for entry in data.get("forces", []) if isinstance(entry, dict) and entry.get("name") == element]
    if len(entries) != 1:
        raise PinstabError(
            f"force element {element!r} of scene {scene.name} is not a [[forces]] entry of a scene file (a scene "
            "built in Python, or an element a robot file or generator adds): a map scales a scene file's element"
        )
    base = next(item for item in scene.forces if item.name == element)
    entries[0]["stiffness"] = factor * base.stiffness
    if scale == "element":
        entries[0]["damping"] = factor * base.damping
    return scene_from_dict(
        data, name=scene.name, base_dir=scene.source.parent, parameters=scene.parameters, source=scene.source
    )


def element_map(
    scene: Scene,
    element: str,
    integrators: list[str] | None = None,
    dt_range: tuple[float, float] = (1e-5, 1e-2),
    factor_range: tuple[float, float] = (1e-2, 1e2),
    grid: int = 40,
    steps: int = 200,
    scale: str = "element",
    progress: bool = False,
) -> ElementMap:
    """Run a grid of ``steps``-step runs of each integrator over (dt, factor), the element scaled by the factor.

    Args:
        scene: a scene read from a file. element: its force element with a stiffness.
        integrators: the schemes (default: every one of :func:`map_integrators`).
        dt_range: smallest and largest step [s] (log-spaced). factor_range: smallest and largest scale [-] (log).
        grid: cells per axis (2 to MAX_GRID). steps: steps per run (at least 2; integrators x grid^2 x steps at most
            MAX_MAP_STEPS).
        scale: ``element`` (stiffness and damping times the factor) or ``stiffness`` (the stiffness alone).
        progress: progress bar on stderr.

    Raises:
        PinstabError: an argument out of its range, naming it. A run that blows up is a ``diverged`` cell.
    """
    integrators = list(integrators or map_integrators())
    unknown = [name for name in integrators if name not in map_integrators()]
    if unknown or len(set(integrators)) != len(integrators):
        raise PinstabError(
            f"integrators {integrators}: each once, among those with a known stability function: "
            f"{choices(map_integrators())}"
        )
    if scale not in SCALES:
        raise PinstabError(f"scale must be one of {choices(SCALES)}, got {scale!r}")
    check_grid({"dt range": dt_range, "factor range": factor_range}, grid, steps, len(integrators))
    base = scaled_scene(scene, element, 1.0, scale)
    base_model = ConstrainedModel(base)
    mode = stiffest_mode(base_model, base.q0, base.v0, 0.0)
    limits = {name: _mode_limit(mode, name) for name in integrators}
    result = ElementMap(scene.name, element, scale, steps, integrators, mode, limits)
    dts = [float(dt) for dt in np.geomspace(*dt_range, grid)]
    bar = progress_bar(len(integrators) * grid * grid, f"stability {scene.name} {element}", progress)
    for factor in np.geomspace(*factor_range, grid):
        scaled = scaled_scene(scene, element, float(factor), scale)
        model = ConstrainedModel(scaled)
        linear = linearize(model, scaled.q0, scaled.v0, 0.0)
        if linear is None:
            raise PinstabError(f"scene {scene.name}: its constraints leave no motion at the start; nothing to map")
        stiffness = np.linalg.solve(linear.mass, linear.stiffness.sum(axis=0))
        damping = np.linalg.solve(linear.mass, linear.damping.sum(axis=0))
        energy_scale = _energy_scale(model, scaled)
        for name in integrators:
            for dt in dts:
                excess = step_growth(name, dt, stiffness, damping).excess
                observed, ratio = _observe(scaled, name, dt, steps, energy_scale)
                result.cells.append(ElementCell(name, dt, float(factor), excess, observed, ratio, steps))
                if bar is not None:
                    bar.update(1)
    if bar is not None:
        bar.close()
    return result


def _energy_scale(model: ConstrainedModel, scene: Scene) -> float:
    """The kinetic and force elements' energy at the start [J]: what a run's gained energy is measured against."""
    model.forces_at(scene.q0, scene.v0, 0.0)  # placements current in model.kin, for the elements' energy
    kinetic = kinetic_energy(model.model, model.scratch, scene.q0, scene.v0)
    stored = sum(item.potential_energy(model.kin) for item in scene.forces)
    if not kinetic + stored > 0.0:
        raise PinstabError(
            f"scene {scene.name}: its start has no kinetic or element energy; a map measures the energy a step gains "
            "against it (give the scene an initial velocity or a stretched element)"
        )
    return float(kinetic + stored)


def _observe(scene: Scene, integrator: str, dt: float, steps: int, energy_scale: float) -> tuple[str, float]:
    """A run's class and its gained energy as a speed ratio (module docstring)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnstableGainsWarning)
        try:
            run = simulate(scene, integrator=integrator, dt=dt, duration=steps * dt, limits=False)
            energy = np.asarray(run.energy)
        except (DivergenceError, ProjectionError) as error:  # blown up (a failed solve on a blown-up state included)
            if isinstance(error, NewtonError) or isinstance(error.__cause__, NewtonError):
                return "unsolved", math.inf  # the stage equation not solved: not a divergence of the scheme
            return "diverged", math.inf
    if not np.isfinite(energy).all():
        return "diverged", math.inf
    ratio = math.sqrt(max(float(energy.max() - energy[0]), 0.0) / energy_scale)
    observed = "dissipative" if ratio <= CONVERGED_RATIO else ("bounded" if ratio <= DIVERGED_RATIO else "diverged")
    return observed, ratio


def _mode_limit(mode: StiffMode | None, scheme: str) -> float:
    """The largest step [s] with which ``scheme`` keeps the stiffest mode inside its region
    (:func:`~pinstab.stability.criterion.mode_step_limit`: inf for an A-stable scheme; NaN without a decaying mode)."""
    return mode_step_limit(mode.eigenvalue, scheme) if mode is not None and mode.decays else math.nan


def plot_element_map(result: ElementMap, path: str | Path) -> Path:
    """Write a PNG: one panel per integrator, observed classes per cell, the predicted boundary
    (``excess^N = DIVERGED_RATIO``) drawn over them."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from ..plotting import pyplot, save_figure

    plt = pyplot()
    dts = np.array(sorted({c.dt for c in result.cells}))
    factors = np.array(sorted({c.factor for c in result.cells}))
    colors = ["#4c9a2a", "#e0b43c", "#c0392b", "#7f7f7f"]
    panels = len(result.integrators)
    rows = math.ceil(panels / PANELS_PER_ROW)
    columns = math.ceil(panels / rows)
    fig, axes = plt.subplots(
        rows, columns, figsize=(4.2 * columns, 4.0 * rows + 0.4), dpi=110, squeeze=False, sharex=True, sharey=True
    )
    for ax in axes.flat[panels:]:
        ax.set_visible(False)
    for index, (ax, name) in enumerate(zip(axes.flat, result.integrators, strict=False)):
        classes = np.zeros((len(factors), len(dts)))
        growth = np.zeros((len(factors), len(dts)))
        for c in (c for c in result.cells if c.integrator == name):
            i, j = int(np.searchsorted(factors, c.factor)), int(np.searchsorted(dts, c.dt))
            classes[i, j] = CLASSES.index(c.observed)
            growth[i, j] = c.steps * math.log10(max(c.excess, 1e-300)) if math.isfinite(c.excess) else 1e300
        ax.pcolormesh(
            log_edges(dts),
            log_edges(factors),
            classes,
            cmap=ListedColormap(colors),
            vmin=-0.5,
            vmax=len(CLASSES) - 0.5,
            shading="flat",
        )
        if growth.min() < math.log10(DIVERGED_RATIO) < growth.max():
            ax.contour(dts, factors, growth, levels=[math.log10(DIVERGED_RATIO)], colors="black", linewidths=2.0)
        ax.set_xscale("log")
        ax.set_yscale("log")
        if index + columns >= panels:  # no panel below it
            ax.set_xlabel("time step dt [s]")
            ax.xaxis.set_tick_params(labelbottom=True)
        ax.set_title(f"{name}: agree on {100 * result.agreement(name):.1f} %", fontsize=10)
    label = "stiffness and damping" if result.scale == "element" else "stiffness"
    for row in axes:
        row[0].set_ylabel(f"{result.element}: {label} x factor")
    handles = [Patch(color=c, label=name) for c, name in zip(colors, CLASSES, strict=True)]
    handles.append(plt.Line2D([], [], color="black", linewidth=2, label=f"predicted: a mode grows {DIVERGED_RATIO:g}x"))
    inch = 1.0 / fig.get_figheight()  # an inch down from the top [figure fraction]
    title = f"{result.scene}: {result.steps}-step runs, observed vs predicted stability"
    fig.suptitle(title, fontsize=11, y=1.0 - 0.1 * inch, va="top")
    legend_top = (0.5, 1.0 - 0.4 * inch)
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=legend_top, ncol=len(handles), fontsize=8)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.75 * inch))  # the panels under the title and the legend
    return save_figure(fig, path)
