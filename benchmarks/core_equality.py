"""Trajectories on the core path against the general path (issue 35: the core must give the present paths' motion):
every bundled scene whose held run takes the core, run by ``pinstab.simulate()`` at its defaults (contacts held as
rows) over DURATION
(Cassie over CASSIE_DURATION: the general path costs ~56 CPU s per simulated second there) and again with
``solver="proxsuite"`` (the general path: pinstab's Python rows, ProxQP's direct Cholesky solve, ProxQP itself where
rows are redundant); the largest difference of any coordinate of q [rad or m] and of v [rad/s or m/s] over the
samples both runs reached (a run that stops, ``allegro-tilt``'s lost grasp, is compared up to its stop, and the stop
times too).

Where the two differ by more than rounding (``delta`` through its singular configurations, ``cassie`` with its redundant
loop rows: ProxQP solves the general path's rank-deficient evaluations), both are also run against an independent
reference: the general path with the KKT system [[M, -G^T], [G, 0]] [a; lambda] = [f; rhs] solved whole (no Delassus
matrix) by least squares with iterative refinement whose residuals are summed in extended precision (``long double``):
the solver ``extended`` (``pinstab/solvers/extended_.py``).

    python benchmarks/core_equality.py    # prints the table, writes benchmarks/results/core_equality.json (~3 min)
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

import pinstab
from pinstab.bench import save_results
from pinstab.errors import PinstabError
from pinstab.readers.sources import bundled_scenes
from pinstab.simulate import default_contacts
from pinstab.system import build_system

DURATION = 2.0  # [s]
CASSIE_DURATION = 0.2  # [s]
OUT = Path(__file__).parent / "results" / "core_equality.json"
REFERENCE_SCENES = ("delta", "cassie")  # the scenes whose general path solves rank-deficient rows by ProxQP


def run(scene: pinstab.Scene, duration: float, **options: Any) -> tuple[pinstab.Trajectory, str | None]:
    """The run (up to where it stopped) and the error that stopped it, if any."""
    try:
        # held: the scene's contacts as rows on both paths (event-driven by default, which takes neither)
        return pinstab.simulate(scene, duration=duration, progress=False, contacts="held", **options), None
    except PinstabError as exc:
        return exc.trajectory, type(exc).__name__


def on_core(scene: pinstab.Scene) -> bool:
    """Whether the scene's default run takes the core path."""
    if default_contacts(scene) not in (None, "held"):  # event-driven contacts take their own path
        return False
    system = build_system(scene)
    system.bind(scene.step or 1e-3, "rk4", scene.q0)
    return system.path == "core"


def main() -> None:
    rows = {}
    for name in bundled_scenes():
        scene = pinstab.load_scene(name)
        if not on_core(scene):
            continue
        duration = CASSIE_DURATION if name == "cassie" else DURATION
        (core, core_stop), (general, general_stop) = run(scene, duration), run(scene, duration, solver="proxsuite")
        n = min(len(core.t), len(general.t))
        rows[name] = {
            "duration_s": duration,
            "paths": [core.info.path, general.info.path],
            "stops": [core_stop, general_stop],
            "t_end_s": [float(core.t[-1]), float(general.t[-1])],
            "max_dq": float(np.max(np.abs(core.q[:n] - general.q[:n]))),
            "max_dv": float(np.max(np.abs(core.v[:n] - general.v[:n]))),
            "general_status": general.info.solver_statistics.status_counts,
        }
        if name in REFERENCE_SCENES:
            reference, _ = run(scene, duration, solver="extended")
            rows[name]["from_extended"] = {
                path: {
                    "max_dq": float(np.max(np.abs(traj.q[:n] - reference.q[:n]))),
                    "max_dv": float(np.max(np.abs(traj.v[:n] - reference.v[:n]))),
                }
                for path, traj in (("core", core), ("general", general))
            }
        row = rows[name]
        print(
            f"{name:<16} {row['max_dq']:9.2e} {row['max_dv']:9.2e}  t_end {row['t_end_s']}  stops {row['stops']}  "
            f"general {row['general_status']}  from extended {row.get('from_extended', '-')}",
            flush=True,
        )
    save_results(OUT, {"scenes": rows})


if __name__ == "__main__":
    main()
