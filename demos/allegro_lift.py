"""
Allegro hand: lift a ball and turn it
=====================================

The Allegro hand lifts a ball 3 cm and turns it 20 degrees by object-level computed torque, headless:
a recording and a chart of the pose error, the smallest friction-cone margin and the joint torques.

.. code-block:: bash

    python demos/allegro_lift.py -o allegro-lift.html --chart allegro-lift.png

(The chart of the documentation's grasp guide: ``python demos/allegro_lift.py -o /tmp/allegro-lift.html
--chart docs/allegro-lift.png``.) The scene is ``robots/allegro-lift.toml``; ``--no-internal-forces`` switches
the internal-force QP off and shows the grasp lost at once.
"""

from __future__ import annotations

import argparse

import numpy as np

import pinstab
from pinstab.errors import GraspLostError
from pinstab.grasp.report import ControlSeries, control_series
from pinstab.model import ConstrainedModel
from pinstab.viz.recording import write_recording


def chart(series: ControlSeries, path: str) -> None:
    """Pose error, smallest cone margin and joint torques against time, one panel each."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    axes[0].semilogy(series.t, np.maximum(series.position_error, 1e-16) * 1e3, label="position [mm]")
    axes[0].semilogy(series.t, np.maximum(np.degrees(series.orientation_error), 1e-16), label="orientation [deg]")
    axes[0].set_ylabel("object pose error")
    axes[0].legend(loc="upper right")
    axes[1].plot(series.t, series.cone_margin)
    axes[1].axhline(0.0, color="red", linewidth=0.8)
    axes[1].set_ylabel("min cone margin\nmu f_n - |f_t| [N]")
    axes[2].plot(series.t, series.torques, linewidth=0.8)
    axes[2].set_ylabel("joint torques [N m]")
    axes[2].set_xlabel("t [s]")
    figure.suptitle("Allegro hand: lift a ball 3 cm and turn it 20 deg (grasp-control)")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def main() -> None:
    parser = argparse.ArgumentParser(
        description="The Allegro hand lifts a ball 3 cm and turns it 20 degrees by object-level computed torque."
    )
    parser.add_argument("-o", "--output", default="allegro-lift.html", help="recording to write")
    parser.add_argument("--chart", default="allegro-lift.png", help="chart to write (PNG)")
    parser.add_argument("--duration", type=float, default=2.0, help="simulated time [s]")
    parser.add_argument("--no-internal-forces", action="store_true", help="switch the internal-force QP off")
    args = parser.parse_args()

    scene = pinstab.load_scene("allegro-lift")
    controller = scene.forces[0]
    controller.internal_forces = not args.no_internal_forces
    try:
        trajectory = pinstab.simulate(scene, dt=1e-3, duration=args.duration, progress=True)
    except GraspLostError as exc:
        print(f"without internal forces: {exc}")
        return
    series = control_series(scene, trajectory, controller)
    recording = write_recording(ConstrainedModel(scene), trajectory, args.output)
    chart(series, args.chart)
    usage = np.max(np.abs(series.torques) / series.effort_limit)
    print(f"max position error: {series.position_error.max():.3e} m")
    print(f"max orientation error: {np.degrees(series.orientation_error.max()):.3e} deg")
    print(f"min cone margin: {series.cone_margin.min():.4f} N")
    print(f"max |joint torque|: {np.abs(series.torques).max():.4f} N m ({100 * usage:.2f} % of the limit)")
    print(f"max position drift: {trajectory.position_drift.max():.3e} m")
    print(f"recording: {recording.path} ({recording.frames} frames); chart: {args.chart}")


if __name__ == "__main__":
    main()
