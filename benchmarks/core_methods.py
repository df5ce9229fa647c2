"""Mukharlyamov's extended system (automatic gains, the term held over RK4's stages) on the core path
against the general path it took before (pinstab's Python rows and term, ProxQP's direct solve: ``solver="proxsuite"``
keeps a run there), as a user runs it (``pinstab run SCENE --method mukharlyamov``: ``pinstab.simulate()``, the whole
call, RK4 at the scene's step): CPU s per simulated second of the kinematic variant on ``delta`` (1 s, the CLI's
default duration) and the full ``cassie`` (0.2 s), and of the inertial variant on ``fourbar`` (2 s), the runs
interleaved and repeated (the least of REPEATS counts), with the ratio and the largest difference of the two runs'
q and v and their position drifts.

    python benchmarks/core_methods.py    # prints the table, writes benchmarks/results/core_methods.json (~2 min)
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

import pinstab
from pinstab.bench import save_results

CASES = {("delta", "kinematic"): 1.0, ("cassie", "kinematic"): 0.2, ("fourbar", "inertial"): 2.0}  # [s] simulated
REPEATS = 3
PATHS = {"core": {}, "general": {"solver": "proxsuite"}}
OUT = Path(__file__).parent / "results" / "core_methods.json"


def timed(scene: pinstab.Scene, duration: float, **options: Any) -> tuple[pinstab.Trajectory, float]:
    """``simulate(scene, "mukharlyamov", **options)`` over ``duration`` [s] and its CPU time [s]."""
    began = time.process_time()
    run = pinstab.simulate(scene, "mukharlyamov", duration=duration, progress=False, **options)
    return run, time.process_time() - began


def measure(name: str, variant: str, duration: float) -> dict[str, Any]:
    scene = pinstab.load_scene(name)
    cpu: dict[str, list[float]] = {path: [] for path in PATHS}
    runs: dict[str, pinstab.Trajectory] = {}
    for _ in range(REPEATS):
        for path, options in PATHS.items():
            runs[path], seconds = timed(scene, duration, variant=variant, **options)
            cpu[path].append(seconds)
    core, general = runs["core"], runs["general"]
    row = {
        "duration_s": duration,
        "paths": [core.info.path, general.info.path],
        "core_cpu_s_per_s": min(cpu["core"]) / duration,
        "general_cpu_s_per_s": min(cpu["general"]) / duration,
        "max_dq": float(np.max(np.abs(core.q - general.q))),
        "max_dv": float(np.max(np.abs(core.v - general.v))),
        "max_position_drift_m": [float(np.max(core.position_drift)), float(np.max(general.position_drift))],
        "core_status": core.info.solver_statistics.status_counts,
        "general_status": general.info.solver_statistics.status_counts,
    }
    row["speedup"] = row["general_cpu_s_per_s"] / row["core_cpu_s_per_s"]
    print(
        f"{name:<8} {variant:<9} {duration:4.1f} s  core {row['core_cpu_s_per_s']:8.3f}  "
        f"general {row['general_cpu_s_per_s']:8.3f} "
        f"CPU s/s  ({row['speedup']:5.1f}x)  |dq| {row['max_dq']:.1e}  |dv| {row['max_dv']:.1e}  drift "
        f"{row['max_position_drift_m'][0]:.2e} / {row['max_position_drift_m'][1]:.2e} m",
        flush=True,
    )
    return row


def main() -> None:
    rows = {f"{name} {variant}": measure(name, variant, duration) for (name, variant), duration in CASES.items()}
    save_results(OUT, {"method": "mukharlyamov", "integrator": "rk4", "repeats": REPEATS, "scenes": rows})


if __name__ == "__main__":
    main()
