"""The full Cassie on the core path (issue 35, first acceptance line): 16 closures (36 rows of rank 28), floating base,
20 joint springs and dampers, RK4 at 1 ms over 2 s, measured as a user runs it (``pinstab.simulate()``, the whole call):
CPU s per simulated second, the largest position drift, the energy balance (E - E(0) - W, W the dampers' work) relative
to the energy, and the trajectory's distance from the same method at 0.1 ms (RK4: the error falls as dt^4). Two starts:
the scene's free fall, and a kicked one (0.5 rad/s on both hip-roll motors, projected onto the closures, joint limits
set aside: the hips reach theirs at 1.2 s), where the springs and dampers work. Side by side in the same run: the
general path (pinstab's Python rows and ProxQP, ``solver="proxsuite"``) at 1 ms over a short run, the cost the core
replaced.

    python benchmarks/cassie_core.py    # prints the table, writes benchmarks/results/cassie_core.json (~1 min)
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

import pinstab
from pinstab.bench import save_results

DURATION = 2.0  # [s]
STEP, FINE = 1e-3, 1e-4  # [s]
GENERAL_DURATION = 0.02  # [s]: the general path's run (its solves cost ~14 ms each)
KICK = {"left-roll-op": 0.5, "right-roll-op": -0.5}  # [rad/s]; the joint limits set aside (reached at 1.2 s)
OUT = Path(__file__).parent / "results" / "cassie_core.json"


def timed(scene: pinstab.Scene, duration: float, dt: float, **options: Any) -> tuple[pinstab.Trajectory, float]:
    """A default ``simulate()`` of ``scene`` and its CPU time [s]."""
    began = time.process_time()
    run = pinstab.simulate(scene, duration=duration, dt=dt, progress=False, **options)
    return run, time.process_time() - began


def measure(label: str, scene: pinstab.Scene, v0: np.ndarray | None) -> dict[str, Any]:
    start = {"v0": v0, "limits": v0 is None}
    run, cpu = timed(scene, DURATION, STEP, **start)
    fine, _ = timed(scene, DURATION, FINE, record_every=round(STEP / FINE), **start)
    general, general_cpu = timed(scene, GENERAL_DURATION, STEP, solver="proxsuite", **start)
    summary = run.summary()
    row = {
        "path": run.info.path,
        "solver_status": run.info.solver_statistics.status_counts,
        "cpu_s_per_s": cpu / DURATION,
        "max_position_drift_m": float(np.max(run.position_drift)),
        "energy_balance_relative": summary.get("energy_balance_relative"),
        "force_work_J": summary.get("force_work"),
        "error_vs_fine_rad_or_m": float(np.max(np.abs(run.q - fine.q))),
        "general_path_cpu_s_per_s": general_cpu / GENERAL_DURATION,
        "general_solver_status": general.info.solver_statistics.status_counts,
        "core_vs_general_over_general_run": float(np.max(np.abs(run.q[: len(general.q)] - general.q))),
    }
    row["speedup_over_general"] = row["general_path_cpu_s_per_s"] / row["cpu_s_per_s"]
    print(
        f"{label:<10} {row['path']:<5} {row['cpu_s_per_s']:8.3f} CPU s/s  drift {row['max_position_drift_m']:.2e} m  "
        f"energy balance {row['energy_balance_relative']:.2e}  vs 0.1 ms {row['error_vs_fine_rad_or_m']:.2e}  "
        f"general path {row['general_path_cpu_s_per_s']:.0f} CPU s/s ({row['speedup_over_general']:.0f}x)",
        flush=True,
    )
    return row


def main() -> None:
    scene = pinstab.load_scene("cassie")
    kicked = np.zeros(scene.model.nv)
    for joint, rate in KICK.items():
        kicked[scene.model.joints[scene.model.getJointId(joint)].idx_v] = rate
    rows = {"free fall": measure("free fall", scene, None), "kicked": measure("kicked", scene, kicked)}
    limits = {"cpu_s_per_s": 1.0, "max_position_drift_m": 1e-8, "energy_balance_relative": 1e-6}
    for label, row in rows.items():
        met = all(row[key] is not None and row[key] <= limit for key, limit in limits.items())
        print(f"{label}: <= 1 CPU s/s, drift <= 1e-8 m, energy balance <= 1e-6: {'met' if met else 'NOT MET'}")
    save_results(OUT, {"duration_s": DURATION, "dt_s": STEP, "fine_dt_s": FINE, "kick_rad_s": KICK, "runs": rows})


if __name__ == "__main__":
    main()
