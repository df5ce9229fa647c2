"""Issue 37's Cassie lines: the full ``cassie`` (cassie.sdf: free flyer, 16 closures, knee and heel springs of 1500 and
1250 N m/rad) over 2 s with the implicit integrators against RK4.

The bundled scene falls from rest: it falls as one rigid body and its springs never move (their work over 2 s is
1e-23 J), so any integrator passes on it. Here its left knee motor starts turning at 1 rad/s (projected onto the
closures, as every start is), which sets the springs working (0.13 J through the dampers over 2 s). Runs, each the
whole ``pinstab.simulate()`` call:

* ``esdirk4`` at rtol = atol = 1e-6 (error control): mean step, largest position drift [m], the largest joint-angle
  difference [rad] from RK4 at 0.1 ms on the 1 ms grid;
* RK4 at 0.1 ms (the reference) and at 5 ms;
* ``implicit-midpoint`` and ``implicit-euler`` at 5 ms: how far they get, and why they stop when they do;
* RK4 at 0.1 ms, ``esdirk4`` at rtol 1e-6 and ``implicit-midpoint`` at 5 ms with ``method="projection"`` (q and v
  projected onto the closures every step): Baumgarte's runs keep a drift of 4e-8 m that is not the integrator's (RK4
  at 0.1 ms keeps the same), because the KKT solve's pseudo-inverse drops the near-singular closure rows' directions;
  the projection (refined by the singular values of G L^-T) holds them. Every run is compared with both RK4 runs at
  0.1 ms (each formulation's reference).

Each row gives the start's velocity residual [m/s or rad/s] (the assembly's: near-singular shin and heel-spring
closures at the start, which D = G M^-1 G^T's pseudo-inverse alone left at 5e-6 m/s) and the energy change [J] beside
the work of the force elements' non-conservative parts (the dampers; the springs' energy is in E) [J]: a scheme that
loses only that has an energy change equal to it; the difference is the scheme's own gain or loss.

    python benchmarks/cassie_implicit.py   # prints the table (~1 min), writes results/cassie_implicit.json
"""

from __future__ import annotations

import time
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

import pinstab
from pinstab.bench import save_results
from pinstab.errors import PinstabError
from pinstab.scene import scene_from_dict

ROBOTS = Path(__file__).resolve().parents[1] / "robots"
OUT = Path(__file__).parent / "results" / "cassie_implicit.json"
DURATION = 2.0  # [s]
REFERENCES = ("rk4 0.1 ms", "rk4 0.1 ms projection")  # the runs every other run's joint angles are compared with
OUTPUT_STEP = 1e-3  # [s] the samples compared
KICK = {"left-knee-op": 1.0}  # [rad/s] the start's joint velocity
RUNS = {
    "esdirk4 rtol 1e-6": {"integrator": "esdirk4", "rtol": 1e-6, "dt": OUTPUT_STEP},
    "rk4 0.1 ms": {"integrator": "rk4", "dt": 1e-4},
    "rk4 5 ms": {"integrator": "rk4", "dt": 5e-3},
    "implicit-midpoint 5 ms": {"integrator": "implicit-midpoint", "dt": 5e-3},
    "implicit-euler 5 ms": {"integrator": "implicit-euler", "dt": 5e-3},
    "rk4 0.1 ms projection": {"integrator": "rk4", "dt": 1e-4, "method": "projection"},
    "esdirk4 rtol 1e-6 projection": {"integrator": "esdirk4", "rtol": 1e-6, "dt": OUTPUT_STEP, "method": "projection"},
    "implicit-midpoint 5 ms projection": {"integrator": "implicit-midpoint", "dt": 5e-3, "method": "projection"},
}


def kicked_cassie() -> pinstab.Scene:
    """The bundled ``cassie`` with its left knee motor turning at the start (:data:`KICK`)."""
    data = tomllib.loads((ROBOTS / "cassie.toml").read_text())
    data["initial"] = {"v": dict(KICK)}
    return scene_from_dict(data, base_dir=ROBOTS, name="cassie-kicked")


def run(scene: pinstab.Scene, options: dict[str, Any]) -> tuple[dict[str, Any], pinstab.Trajectory | None]:
    """One run's figures: reached time [s], CPU s, steps, drift [m], energy balance error [J], Newton's figures, or
    the error that stopped it (its partial trajectory kept)."""
    start = time.process_time()
    try:
        traj = pinstab.simulate(scene, duration=DURATION, **options)
        stopped = None
    except PinstabError as error:
        traj, stopped = getattr(error, "trajectory", None), f"{type(error).__name__}: {str(error)[:300]}"
    cpu = time.process_time() - start
    if traj is None:
        return {"stopped": stopped, "cpu_s": cpu}, None
    summary = traj.summary()
    control = summary.get("error_control") or {}
    steps = control.get("steps_accepted") or round(float(traj.t[-1]) / options["dt"])
    assembly = traj.info.assembly
    return {
        "start_velocity_residual": None if assembly is None else assembly.velocity_residual,
        "t_end": float(traj.t[-1]),
        "cpu_s": cpu,
        "steps": steps,
        "mean_step": float(traj.t[-1]) / steps if steps else None,
        "max_position_drift": summary["max_position_drift"],
        "energy_start": float(traj.energy[0]),
        "energy_end": float(traj.energy[-1]),
        "energy_change": float(traj.energy[-1] - traj.energy[0]),
        "force_work": summary.get("force_work"),
        "max_energy_balance_error": summary.get("max_energy_balance_error"),
        "newton": summary.get("newton"),
        "stopped": stopped,
    }, traj


def joint_difference(traj: pinstab.Trajectory, reference: pinstab.Trajectory, nq_base: int = 7) -> float:
    """The largest joint-angle difference [rad] (the free flyer's 7 coordinates left out) on traj's samples that fall on
    the reference's grid."""
    index = np.rint(traj.t / (reference.t[1] - reference.t[0])).astype(int)
    inside = index < len(reference.t)
    return float(np.abs(traj.q[inside, nq_base:] - reference.q[index[inside], nq_base:]).max())


def main() -> None:
    scene = kicked_cassie()
    rows: dict[str, dict[str, Any]] = {}
    trajectories: dict[str, pinstab.Trajectory | None] = {}
    for label, options in RUNS.items():
        rows[label], trajectories[label] = run(scene, options)
    for reference_label in REFERENCES:
        reference = trajectories[reference_label]
        for label, traj in trajectories.items():
            if traj is not None and reference is not None and label != reference_label:
                key = "joint_difference_from_" + reference_label.replace(" ", "_")
                rows[label][key] = joint_difference(traj, reference)
    for label, row in rows.items():
        figures = ", ".join(f"{key} {value:.4g}" for key, value in row.items() if isinstance(value, float))
        print(f"{label:34s} {figures}")
        if row.get("stopped"):
            print(f"{'':34s} stopped: {row['stopped']}")
    save_results(OUT, {"scene": "cassie, left knee motor at 1 rad/s", "duration": DURATION, "runs": rows})


if __name__ == "__main__":
    main()
