"""Why the special paths stay (issue 35, item 4): the core kernel against the native and banded kernels on the scenes
they take, the same equations (Baumgarte, Kp = 100, Kd = 20), stepped by the same compiled RK4 loop at 1 ms over
DURATION, interleaved, ROUNDS rounds, the median CPU s per simulated second: the four-bar (native: Pinocchio's
``constraintDynamics``) and the N-four-bar at N = 10, 40 and 80 (banded: the banded LU), with the largest difference
of their trajectories.

    python benchmarks/core_vs_special.py    # prints the table, writes benchmarks/results/core_vs_special.json (~1 min)
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import pinstab
from pinstab.bench import save_results
from pinstab.integration.compiled import SCHEMES
from pinstab.model import ConstrainedModel
from pinstab.paths.core import CoreDynamics
from pinstab.simulate.loop import start_state
from pinstab.solvers.base import ACCEPTED_RESIDUAL
from pinstab.solvers.proxsuite_ import DIRECT_PIVOT
from pinstab.system import build_system

DURATION, DT, ROUNDS = 2.0, 1e-3, 5
CASES = {"fourbar": {}, "nfourbar N=10": {"N": 10}, "nfourbar N=40": {"N": 40}, "nfourbar N=80": {"N": 80}}
OUT = Path(__file__).parent / "results" / "core_vs_special.json"


def main() -> None:
    rows = {}
    for label, parameters in CASES.items():
        scene = pinstab.load_scene(label.split()[0], **parameters)
        q, v = start_state(scene, None, None)
        system = build_system(scene)
        system.bind(DT, "rk4", q)
        special = system.banded.kernel if system.banded is not None else system.native.kernel()
        term = system.stabilizer.core_term()  # Baumgarte's at its defaults, Kp = 100, Kd = 20
        core = CoreDynamics(ConstrainedModel(scene), term, DIRECT_PIVOT, ACCEPTED_RESIDUAL).kernel
        kernels = {system.path: special, "core": core}
        tau, steps = np.zeros(scene.model.nv), round(DURATION / DT)
        times: dict[str, list[float]] = {name: [] for name in kernels}
        runs = {}
        for _ in range(ROUNDS):
            for name, kernel in kernels.items():
                began = time.process_time()
                runs[name] = kernel.run(SCHEMES["rk4"], q, v, tau, DT, steps, 0)
                times[name].append((time.process_time() - began) / DURATION)
        cost = {name: float(np.median(values)) for name, values in times.items()}
        difference = float(np.max(np.abs(runs["core"][0] - runs[system.path][0])))
        rows[label] = {
            "special_path": system.path,
            "cpu_s_per_s": cost,
            "core_over_special": cost["core"] / cost[system.path],
            "max_dq": difference,
        }
        print(
            f"{label:<14} {system.path:<7} {cost[system.path]:.4f}  core {cost['core']:.4f}  "
            f"core / {system.path} {rows[label]['core_over_special']:.2f}  max |dq| {difference:.1e}",
            flush=True,
        )
    save_results(OUT, {"duration_s": DURATION, "dt_s": DT, "rounds": ROUNDS, "cases": rows})


if __name__ == "__main__":
    main()
