"""Charts of a trajectory: drift, energy error and constraint forces against time."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..plotting import pyplot, save_figure
from ..trajectory import Trajectory


def plot_trajectory(trajectory: Trajectory, path: str | Path) -> Path:
    """Write :func:`trajectory_figure` as a PNG."""
    return save_figure(trajectory_figure(trajectory), path)


def trajectory_figure(trajectory: Trajectory):
    """Three panels sharing the time axis [s]:

    * position drift max|phi| [m] and velocity drift max|g| [m/s], log scale;
    * energy error E(t) - E(0) [J];
    * the norm of each constraint's multipliers [N];
    * with prescribed constraints, the controls u that realize them [N m or N].
    """
    plt = pyplot()
    t = trajectory.t
    info = trajectory.info
    servo = trajectory.servo_figures
    fig, axes = plt.subplots(4 if servo else 3, 1, figsize=(7.5, 10.5 if servo else 8.0), dpi=110, sharex=True)
    drift_axis, energy_axis, force_axis = axes[:3]
    floor = np.finfo(float).tiny
    drift_axis.semilogy(t, np.maximum(trajectory.position_drift, floor), label="position drift max|phi| [m]")
    drift_axis.semilogy(t, np.maximum(trajectory.velocity_drift, floor), label="velocity drift max|g| [m/s]")
    drift_axis.set_ylabel("constraint drift [m], [m/s]")
    drift_axis.legend(fontsize=8)
    energy_axis.plot(t, trajectory.energy - trajectory.energy[0], color="tab:green")
    energy_axis.set_ylabel("energy error E(t) - E(0) [J]")
    for name, (start, stop) in info.constraint_rows.items():
        norms = np.linalg.norm(trajectory.multipliers[:, start:stop], axis=1)
        force_axis.plot(t, norms, label=name)
    force_axis.set_ylabel("constraint force |lambda| [N]")
    if info.constraint_rows:
        force_axis.legend(fontsize=8)
    if servo:
        for name, column in zip(info.controls, servo["controls"].T, strict=True):
            axes[3].plot(t, column, label=name)
        axes[3].set_ylabel("controls u [N m or N]")
        axes[3].legend(fontsize=8)
    axes[-1].set_xlabel("time t [s]")
    for axis in axes:
        axis.grid(True, alpha=0.3)
    method = info.method
    fig.suptitle(f"{info.scene}: {method} + {info.integrator}, dt = {info.dt} s", fontsize=10)
    fig.tight_layout()
    return fig
