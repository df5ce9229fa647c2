"""Work-precision of the N-four-bar N = 40 over 20 s (issue 23): crank error against the exact reduced ODE
(the parallelogram pendulum, ``--reference exact``) against CPU time per simulated second, pinstab's default path
(banded, compiled loop) with RK4 at several steps against MuJoCo with each of its integrators (Euler,
implicitfast, RK4) at 1e-3, 1e-4 and 1e-5 s (solref time constant 2 dt, its stiffest advised; loops as
``connect`` equalities), every run in this one process one after another.

python benchmarks/chain_work_precision.py    # ~10 min; writes benchmarks/nfourbar40/ (results, work_precision.png)

It prints, for every MuJoCo run, the cheapest pinstab run at that error or better and the ratio of their costs.
"""

from __future__ import annotations

import math
from pathlib import Path

from pinstab.bench.workprecision import MUJOCO_DTS, MUJOCO_INTEGRATORS, Config, sweep, write_outputs

OUT = Path(__file__).parent / "nfourbar40"
PARAMETERS = {"N": 40}
DURATION = 20.0  # [s]: 20 s of the parallelogram's motion through its singular configurations
PINSTAB_DTS = (7e-2, 6e-2, 5e-2, 4e-2, 2e-2, 1e-2, 8e-3, 4e-3, 2e-3, 1e-3, 5e-4)  # [s] RK4


def main() -> None:
    configs = [Config("baumgarte", "rk4", dt) for dt in PINSTAB_DTS]
    configs += [
        Config("mujoco", scheme, dt, "mujoco", solref=(2 * dt, 1.0))
        for scheme in MUJOCO_INTEGRATORS
        for dt in MUJOCO_DTS
    ]
    reference, results = sweep("nfourbar", PARAMETERS, configs, DURATION, serial=True, show_progress=True)
    write_outputs(OUT, "nfourbar", reference, results, {"duration": DURATION, "parameters": PARAMETERS})
    ours = [r for r in results if r.config.peer is None and not r.diverged]
    print("MuJoCo run                            error [rad]  cost [s/s] | cheapest pinstab at <= that error   ratio")
    for run in (r for r in results if r.config.peer == "mujoco"):
        if run.diverged or not math.isfinite(run.trajectory_error):
            print(f"{run.config.curve} dt={run.config.dt:g}: diverged ({run.note})")
            continue
        within = [r for r in ours if r.trajectory_error <= run.trajectory_error]
        best = min(within, key=lambda r: r.cpu_per_sim_s, default=None)
        label = f"{run.config.integrator} dt={run.config.dt:g}"
        ratio = run.cpu_per_sim_s / best.cpu_per_sim_s if best is not None else math.nan
        if best is None:
            print(f"{label:36s} {run.trajectory_error:10.2e}  {run.cpu_per_sim_s:10.3g} | none reaches it")
            continue
        print(
            f"{label:36s} {run.trajectory_error:10.2e}  {run.cpu_per_sim_s:10.3g} | rk4 dt={best.config.dt:g}: "
            f"{best.trajectory_error:.2e} at {best.cpu_per_sim_s:.3g} s/s   {ratio:6.1f}x"
        )


if __name__ == "__main__":
    main()
