"""Steps for the four-bar, started 0.05 rad off the manifold, to bring its position drift below 1e-10.

Columns: mukharlyamov with automatic gains and semi-implicit Euler (issue 3's acceptance line),
Baumgarte with Pinocchio's example gains (Kp = 10, Kd = 2 sqrt(10)) and the same integrator, and,
for contrast, mukharlyamov with RK4 (term held over the step). "-" means not within 300 steps; the
smallest drift reached is printed beside it.

    python benchmarks/repair_steps.py       # prints the table, writes benchmarks/results/repair_steps.json
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

import pinstab
from pinstab.assembly import perturbed_start
from pinstab.bench import save_results

STEPS = (1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2e-2)
TARGET = 1e-10
HORIZON = 300
CONFIGURATIONS = {
    "mukharlyamov auto, semi-implicit-euler": dict(method="mukharlyamov", integrator="semi-implicit-euler"),
    "baumgarte Kp=10, semi-implicit-euler": dict(
        method="baumgarte", kp=10.0, kd=2 * math.sqrt(10.0), integrator="semi-implicit-euler"
    ),
    "mukharlyamov auto, rk4": dict(method="mukharlyamov", integrator="rk4"),
}
OUT = Path(__file__).parent / "results" / "repair_steps.json"


def main() -> None:
    scene = pinstab.load_scene("fourbar")
    q_off, v0 = perturbed_start(pinstab.ConstrainedModel(scene), 0.05)
    rows = []
    print(f"{'dt [s]':>8}  " + "  ".join(f"{name:>40}" for name in CONFIGURATIONS))
    for dt in STEPS:
        row = {"dt": dt}
        for name, options in CONFIGURATIONS.items():
            traj = pinstab.simulate(
                scene,
                dt=dt,
                duration=HORIZON * dt,
                solver="dense",
                q0=q_off,
                v0=v0,
                assemble_initial=False,
                **options,
            )
            below = np.flatnonzero(traj.position_drift < TARGET)
            row[name] = {
                "steps": int(below[0]) if below.size else None,
                "min_drift": float(traj.position_drift.min()),
                "initial_drift": float(traj.position_drift[0]),
            }
        rows.append(row)
        cells = [
            f"{(str(row[n]['steps']) if row[n]['steps'] is not None else '-'):>5} (min {row[n]['min_drift']:.1e})"
            for n in CONFIGURATIONS
        ]
        print(f"{dt:>8g}  " + "  ".join(f"{c:>40}" for c in cells), flush=True)
    save_results(OUT, {"rows": rows})


if __name__ == "__main__":
    main()
