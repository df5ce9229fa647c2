"""cassie-stand's contact modes evaluated by the compiled core against the numpy evaluation they had (issue 36: the
full Cassie, 16 loop closures, standing on four foot contacts found from geometry, event-driven): CPU seconds per
simulated second of a short run both ways, and the microseconds of one evaluation in the run's modes (every contact
sticking) both ways, each measured interleaved in one run (REPEATS times, the least kept), their ratios, and the
largest difference of q between the two runs.

"before" evaluates each mode by :class:`~pinstab.solvers.contact_modes.ModeDynamics` (a Pinocchio pass from Python, the
held rows' SVD and dense numpy solves), "after" by :class:`~pinstab.solvers.core_modes.CoreModeDynamics` (one call of
the core kernel, ``cpp/contact_modes.cpp``). The 10 s figure of the acceptance line is the CLI's own:
``pinstab run cassie-stand --duration 10 --json`` (its CPU time over 10).

    python benchmarks/cassie_stand_core.py    # prints the table, writes benchmarks/results/cassie_stand_core.json
"""

from __future__ import annotations

import importlib
import time
from pathlib import Path

import numpy as np

import pinstab
from pinstab.bench import save_results
from pinstab.contact.modes import Mode
from pinstab.simulate.contacts import contact_system
from pinstab.solvers.contact_modes import ModeDynamics
from pinstab.solvers.core_modes import CoreModeDynamics

contacts_module = importlib.import_module("pinstab.simulate.contacts")  # the module (pinstab.simulate: the function)
REPEATS = 3
DURATION = 0.2  # [s] of the run
CALLS = 500  # evaluations per timing
OUT = Path(__file__).parent / "results" / "cassie_stand_core.json"
EVALUATIONS = {"before": ModeDynamics, "after": CoreModeDynamics}


def timed_run(scene: pinstab.Scene, evaluation: str) -> tuple[float, pinstab.Trajectory]:
    """CPU seconds per simulated second of a run with that evaluation of its modes, and the run."""
    contacts_module.CoreModeDynamics = EVALUATIONS[evaluation]
    try:
        start = time.process_time()
        run = pinstab.simulate(scene, contacts="event", duration=DURATION, progress=False)
        return (time.process_time() - start) / DURATION, run
    finally:
        contacts_module.CoreModeDynamics = CoreModeDynamics


def evaluation_cost(scene: pinstab.Scene, evaluation: str) -> float:
    """Microseconds per evaluation of the accelerations at the start, every contact sticking (a new time each call:
    ModeDynamics keeps the last state's terms)."""
    contacts, system, q, v, _ = contact_system(scene, scene.q0, np.zeros(scene.model.nv), closures=True)
    dynamics = EVALUATIONS[evaluation](system.model, contacts)
    dynamics.modes = [Mode.STICKING] * len(contacts)
    start = time.process_time()
    for call in range(CALLS):
        dynamics.acceleration(q, v, call * 1e-9)
    return (time.process_time() - start) / CALLS * 1e6


def main() -> None:
    scene = pinstab.load_scene("cassie-stand")
    cpu = {"before": np.inf, "after": np.inf}
    cost = {"before": np.inf, "after": np.inf}
    runs = {}
    for _ in range(REPEATS):
        for evaluation in ("before", "after"):  # interleaved: the machine's load falls on both alike
            seconds, runs[evaluation] = timed_run(scene, evaluation)
            cpu[evaluation] = min(cpu[evaluation], seconds)
            cost[evaluation] = min(cost[evaluation], evaluation_cost(scene, evaluation))
    before, after = runs["before"], runs["after"]
    results = {
        "duration_s": DURATION,
        "status_before": before.info.solver_statistics.status_counts,
        "status_after": after.info.solver_statistics.status_counts,
        "cpu_s_per_s_before": cpu["before"],
        "cpu_s_per_s_after": cpu["after"],
        "speedup": cpu["before"] / cpu["after"],
        "evaluation_us_before": cost["before"],
        "evaluation_us_after": cost["after"],
        "evaluation_speedup": cost["before"] / cost["after"],
        "max_dq_rad": float(np.max(np.abs(before.q - after.q))),
        "events_before": len(before.info.contact_events),
        "events_after": len(after.info.contact_events),
    }
    print(
        f"cassie-stand {DURATION} s: before {cpu['before']:.2f} after {cpu['after']:.2f} CPU s/s "
        f"({results['speedup']:.2f}x); one evaluation: before {cost['before']:.0f} us, after {cost['after']:.0f} us "
        f"({results['evaluation_speedup']:.2f}x); max |dq| {results['max_dq_rad']:.2e} rad; events "
        f"{results['events_before']} / {results['events_after']}",
        flush=True,
    )
    save_results(OUT, results)


if __name__ == "__main__":
    main()
