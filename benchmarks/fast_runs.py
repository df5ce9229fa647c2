"""Grasp, rolling and servo runs at their default settings (issue 23, item 2): CPU seconds per simulated
second of ``pinstab.simulate()`` (the whole call, defaults: Baumgarte, RK4, the scene's step), and each
servo scene against the same scene without its servo (the ``servos`` and ``actuation`` tables removed:
the mechanism moves freely under gravity and its forces; its default run takes Pinocchio's ABA, the native
path, and for context also the general path, ``solver="dense"``), all runs interleaved, median of ROUNDS.

    python benchmarks/fast_runs.py    # prints the table and the ratios, writes benchmarks/results/fast_runs.json

The acceptance lines: ``allegro-sphere`` <= 1 CPU s/s, ``allegro-lift`` <= 2 CPU s/s, a servo scene <= 3x the
same scene without the servo (``benchmarks/grasp_admm.py`` measures ``allegro-sphere`` against the ADMM loop).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import pinstab
from pinstab.bench import save_results
from pinstab.readers.sources import bundled_scenes
from pinstab.scene import scene_from_dict
from pinstab.validation import read_scene_file

DURATION = 1.0  # [s] simulated per run
ROUNDS = 3
SCENES = ["allegro-sphere", "allegro-lift", "finger-rolling", "two-cars", "double-pendulum-servo"]
SERVO_SCENES = ["two-cars", "double-pendulum-servo"]
LIMITS = {"allegro-sphere": 1.0, "allegro-lift": 2.0}  # [CPU s per simulated s]
SERVO_LIMIT = 3.0  # a servo scene's cost over the same scene without the servo
OUT = Path(__file__).parent / "results" / "fast_runs.json"


def without_servo(name: str) -> pinstab.Scene:
    """The bundled scene ``name`` with its ``servos`` and ``actuation`` tables removed."""
    path = bundled_scenes()[name]
    data = {key: value for key, value in read_scene_file(path).items() if key not in ("servos", "actuation")}
    return scene_from_dict(data, name=f"{name} without servo", base_dir=path.parent)


def cpu_per_second(scene: pinstab.Scene, solver: str | None) -> tuple[float, str, int]:
    """(CPU s per simulated s of a default ``simulate()`` over DURATION (``solver`` named or not), the path it
    took, its steps)."""
    began = time.process_time()
    trajectory = pinstab.simulate(scene, duration=DURATION, solver=solver)
    return (time.process_time() - began) / DURATION, trajectory.info.path, len(trajectory.t) - 1


def main() -> None:
    runs = {name: (pinstab.load_scene(name), None) for name in SCENES}
    for name in SERVO_SCENES:
        free = without_servo(name)
        runs[f"{name} without servo"] = (free, None)
        runs[f"{name} without servo, general path"] = (free, "dense")
    times: dict[str, list[float]] = {name: [] for name in runs}
    paths: dict[str, str] = {}
    steps: dict[str, int] = {}
    for _ in range(ROUNDS):
        for name, (scene, solver) in runs.items():
            cpu, paths[name], steps[name] = cpu_per_second(scene, solver)
            times[name].append(cpu)
    cost = {name: float(np.median(values)) for name, values in times.items()}
    print(f"{'scene':50s} {'CPU s/s':>8s} {'us/step':>8s}  path")
    for name, value in cost.items():
        print(f"{name:50s} {value:8.3f} {value * DURATION * 1e6 / steps[name]:8.1f}  {paths[name]}")
    lines = {}
    for name, limit in LIMITS.items():
        lines[f"{name} default run <= {limit:g} CPU s/s"] = {"value": cost[name], "met": cost[name] <= limit}
    for name in SERVO_SCENES:
        ratio = cost[name] / cost[f"{name} without servo"]
        lines[f"{name} <= {SERVO_LIMIT:g}x without its servo"] = {"value": ratio, "met": ratio <= SERVO_LIMIT}
        general = cost[name] / cost[f"{name} without servo, general path"]
        print(f"{name} against its servo-free scene on the general path: {general:.2f}x (context)")
    for line, entry in lines.items():
        print(f"{line:50s} {entry['value']:7.3f}  {'MET' if entry['met'] else 'NOT MET'}")
    save_results(
        OUT,
        {
            "duration_s": DURATION,
            "rounds": ROUNDS,
            "cpu_s_per_simulated_s": cost,
            "all_rounds": times,
            "paths": paths,
            "acceptance": lines,
        },
    )


if __name__ == "__main__":
    main()
