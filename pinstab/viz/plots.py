"""Charts of a trajectory: drift, energy budget and constraint forces against time; for event-driven
contacts, each contact's mode over time and its normal and friction forces."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..analysis.energy import EnergyBudget, energy_budget
from ..errors import PinstabError
from ..plotting import pyplot, save_figure
from ..scene import Scene, load_scene
from ..solvers.contact_modes import plane_geometries
from ..solvers.contact_states import contact_states, mode_spans
from ..trajectory import Trajectory
from .contacts import MODE_COLORS

LABEL_SPACING = 0.02  # contact events are labelled at times this fraction of the time axis apart (all are marked)
LABELS_PER_TIME = 3  # ... with this many events each, then "+n"
WORK_COLORS = ("tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")  # not E's, the error's


def plot_trajectory(trajectory: Trajectory, path: str | Path, scene: Scene | None = None) -> Path:
    """Write :func:`trajectory_figure` as a PNG."""
    return save_figure(trajectory_figure(trajectory, scene), path)


def trajectory_figure(trajectory: Trajectory, scene: Scene | None = None):
    """Panels sharing the time axis [s]:

    * position drift max|phi| [m] and velocity drift max|g| [m/s], log scale over the positive samples
      (a drift of exactly 0, at the start of most runs, is left out rather than drawn at 1e-300);
    * the energy change E(t) - E(0) [J] and the work W(t) [J] of what is meant to change it (dampers, motors,
      loads, servo controls, impacts: :func:`~pinstab.analysis.energy.energy_budget`), then in a panel of its own the
      energy error E(t) - E(0) - W(t) [J]; without such work, the one panel E(t) - E(0), called the energy error
      only when nothing the budget cannot count (sliding friction, time-stepping impulses, ...) did work;
    * the norm of each constraint's multipliers [N]; with event-driven contacts instead each contact's
      normal force (solid) and friction force magnitude (dashed) [N] at the samples (:func:`contact_panels`);
    * with prescribed constraints, the controls u that realize them [N m or N];
    * with a comparison (``--reference``), the trajectory error of each compared coordinate [rad or m];
    * with contact events, a vertical marker at each event's time on every panel, labelled
      ``contact: from -> to`` (:func:`mark_events`).
    * with event-driven contacts, each contact's mode over time: a bar per contact coloured by mode
      (:data:`~pinstab.viz.contacts.MODE_COLORS`) from event to event, impacts marked by triangles.

    ``scene``: the run's scene, for the contact forces; None reloads it by name and parameters (bundled
    scenes), or draws the forces at the events only when that fails.
    """
    plt = pyplot()
    t = trajectory.t
    info = trajectory.info
    servo = trajectory.servo_figures
    comparison = trajectory.comparison
    events = info.contact_events
    budget = energy_budget(trajectory, scene)
    panels = (
        ("drift", True),
        ("energy", True),
        ("remainder", bool(budget.work)),
        ("force", True),
        ("servo", servo),
        ("error", comparison is not None),
        ("modes", bool(events)),
    )
    names = [panel for panel, present in panels if present]
    fig, axes = plt.subplots(len(names), 1, figsize=(7.5, 8.0 + 2.5 * (len(names) - 3)), dpi=110, sharex=True)
    axis = dict(zip(names, axes, strict=True))
    drift_axis, force_axis = axis["drift"], axis["force"]
    _log_panel(
        drift_axis,
        t,
        {
            "position drift max|phi| [m]": trajectory.position_drift,
            "velocity drift max|g| [m/s]": trajectory.velocity_drift,
        },
    )
    drift_axis.set_ylabel("constraint drift [m], [m/s]")
    energy_panels(axis["energy"], axis.get("remainder"), budget)
    if events:
        contact_panels(axis["modes"], force_axis, trajectory, scene)
    else:
        for name, (start, stop) in info.constraint_rows.items():
            norms = np.linalg.norm(trajectory.multipliers[:, start:stop], axis=1)
            force_axis.plot(t, norms, label=name)
        force_axis.set_ylabel("constraint force |lambda| [N]")
        if info.constraint_rows:
            force_axis.legend(fontsize=8)
    if servo:
        servo_axis = axis["servo"]
        for name, column in zip(info.controls, servo["controls"].T, strict=True):
            servo_axis.plot(t, column, label=name)
        servo_axis.set_ylabel("controls u [N m or N]")
        servo_axis.legend(fontsize=8)
    if comparison is not None:
        error_axis = axis["error"]
        labels = [f"{name} [{unit}]" for name, unit in zip(comparison.names, comparison.units, strict=True)]
        _log_panel(error_axis, t, dict(zip(labels, comparison.error.T, strict=True)))
        error_axis.set_ylabel("trajectory error")
        error_axis.set_title(f"against {comparison.reference}", fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    for axis in axes:
        axis.grid(True, alpha=0.3)
    mark_events(axes, info.contact_events)
    method = info.method
    fig.suptitle(f"{info.scene}: {method} + {info.integrator}, dt = {info.dt} s", fontsize=10)
    fig.tight_layout()
    return fig


def energy_panels(energy_axis, remainder_axis, budget: EnergyBudget) -> None:
    """The energy change E(t) - E(0) [J] with the work of each counted term W [J] (dashed) on ``energy_axis``, and the
    energy error E(t) - E(0) - W(t) [J] on ``remainder_axis`` (None when no term is counted: the change alone, the
    energy error only when nothing uncounted did work); what is not counted noted on the panel holding it."""
    t = budget.t
    energy_axis.plot(t, budget.change, color="tab:green", label="E(t) - E(0)")
    uncounted = f"not counted: {', '.join(budget.uncounted)}" if budget.uncounted else ""
    if remainder_axis is None:
        error = "energy error" if not budget.uncounted else "energy change"
        energy_axis.set_ylabel(f"{error} E(t) - E(0) [J]")
        _note(energy_axis, uncounted)
        return
    for index, (name, work) in enumerate(budget.work.items()):
        color = WORK_COLORS[index % len(WORK_COLORS)]
        energy_axis.plot(t, work, linestyle="--", color=color, label=f"work of {name}")
    if len(budget.work) > 1:
        energy_axis.plot(t, budget.counted, linestyle=":", color="black", label="W(t), their sum")
    energy_axis.set_ylabel("energy change, work [J]")
    energy_axis.legend(fontsize=8)
    remainder_axis.plot(t, budget.remainder, color="tab:red", label="E(t) - E(0) - W(t)")
    remainder_axis.set_ylabel("energy error E - E(0) - W [J]")
    remainder_axis.legend(fontsize=8, loc="upper left")
    _note(remainder_axis, uncounted)


def _note(axis, text: str) -> None:
    """A small note in the lower left corner of ``axis`` (nothing for an empty one)."""
    if text:
        axis.text(0.01, 0.03, text, transform=axis.transAxes, fontsize=7, va="bottom", ha="left", color="tab:gray")


def _log_panel(axis, t: np.ndarray, series: dict[str, np.ndarray]) -> None:
    """Log-scale curves of non-negative series over their positive samples (zeros and non-finite values
    left out, so the axis spans the data); a note when no sample is positive."""
    positive = False
    for label, values in series.items():
        shown = np.where(np.isfinite(values) & (values > 0), values, np.nan)
        positive = positive or bool(np.any(np.isfinite(shown)))
        axis.plot(t, shown, label=label)
    axis.set_yscale("log")
    if positive:
        axis.legend(fontsize=8)
    else:
        axis.text(0.5, 0.5, "exactly 0 at every sample", transform=axis.transAxes, ha="center", va="center")


def mark_events(axes, events: list[dict]) -> None:
    """A dotted vertical line at the time [s] of each contact event that changes a mode on every axis, and on
    the first axis labels ``contact: from -> to`` of the events at a time, at times at least
    :data:`LABEL_SPACING` of the axis apart (the rest are in the events table)."""
    by_time: dict[float, list[str]] = {}
    for event in events:
        if event["from"] != event["to"]:
            by_time.setdefault(float(event["t"]), []).append(f"{event['contact']}: {event['from']} -> {event['to']}")
    low, high = axes[0].get_xlim()
    labelled = -math.inf
    for time, labels in by_time.items():
        for axis in axes:
            axis.axvline(time, color="tab:gray", linestyle=":", linewidth=0.8)
        if time - labelled >= LABEL_SPACING * (high - low):
            labelled = time
            more = len(labels) - LABELS_PER_TIME
            text = "\n".join(labels[:LABELS_PER_TIME] + ([f"+{more}"] if more > 0 else []))
            axes[0].text(
                time, 1.0, text, transform=axes[0].get_xaxis_transform(), rotation=90, fontsize=6, va="top", ha="right"
            )


def contact_panels(mode_axis, force_axis, trajectory: Trajectory, scene: Scene | None) -> None:
    """The modes of an event-driven run's contacts (a bar per contact, one coloured span per mode from the
    event that began it to the one that ended it [s], impacts as triangles) and their forces [N]."""
    info = trajectory.info
    events = info.contact_events
    names = list(dict.fromkeys(event["contact"] for event in events))
    states = _states(trajectory, scene)
    spans = mode_spans(events, names, float(trajectory.t[-1])) if states is None else states.spans
    for row, name in enumerate(names):
        mine = [span for span in spans if span.contact == name]
        mode_axis.barh(
            [row] * len(mine),
            [span.end - span.start for span in mine],
            left=[span.start for span in mine],
            height=0.6,
            color=[MODE_COLORS[span.mode] for span in mine],
        )
        impacts = [event["t"] for event in events if event["contact"] == name and event["to"] == "closing"]
        mode_axis.plot(impacts, [row] * len(impacts), "kv", markersize=4)
    mode_axis.set_yticks(range(len(names)), names, fontsize=8)
    mode_axis.set_ylim(len(names) - 0.5, -1.3)  # room above the bars for the legend
    mode_axis.set_ylabel("contact mode")
    plt = pyplot()
    handles = [plt.Rectangle((0, 0), 1, 1, color=color) for color in MODE_COLORS.values()]
    handles.append(plt.Line2D([], [], color="k", marker="v", linestyle="none", markersize=4))
    mode_axis.legend(handles, [*MODE_COLORS, "impact"], fontsize=8, loc="upper right", ncol=4)
    for row, name in enumerate(names):
        color = f"C{row}"
        if states is None:  # the forces at the events only
            at = [event for event in events if event["contact"] == name]
            times = [event["t"] for event in at]
            force_axis.plot(times, [event["force"][0] for event in at], "o", color=color, label=f"{name} normal")
            friction = [float(np.hypot(*event["force"][1:3])) for event in at]
            force_axis.plot(times, friction, "x", color=color, label=f"{name} friction")
            continue
        column = states.names.index(name)
        force_axis.plot(states.t, states.normal_force[:, column], "-", color=color, label=f"{name} normal")
        force_axis.plot(states.t, states.tangential_force[:, column], "--", color=color, label=f"{name} friction")
    force_axis.set_ylabel("contact force [N]" if states is not None else "contact force at the events [N]")
    force_axis.legend(fontsize=7, ncol=2)


def _states(trajectory: Trajectory, scene: Scene | None):
    """The run's contact states, with ``scene`` or the bundled scene of the run's name and parameters;
    None when there is no such bundled scene or it does not match the run."""
    if scene is not None:  # its events may be joint limits' only: no contact states then, the events' forces
        return contact_states(scene, trajectory) if plane_geometries(scene.constraints) else None
    info = trajectory.info
    try:
        return contact_states(load_scene(info.scene, **info.scene_parameters), trajectory)
    except PinstabError:  # not a bundled scene, or not this run's
        return None
