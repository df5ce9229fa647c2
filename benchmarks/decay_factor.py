"""Measure the per-step decay factor r of mukharlyamov's automatic gains, to choose its default.

For each integrator, step and r, on the bundled four-bar:

* ``steps``: steps until a start 0.05 rad off the manifold is brought within 1e-3 of its initial
  position drift (how fast the method repairs a violation);
* ``floor``: the largest position drift over 2 s from a consistent start (what the method costs in
  accuracy once on the manifold), beside Baumgarte at Kp = 100, Kd = 20.

    python benchmarks/decay_factor.py            # prints the table, writes benchmarks/results/decay_factor.json
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import pinstab
from pinstab.assembly import perturbed_start
from pinstab.bench import save_results

DECAYS = (0.0, 0.3, 0.5, 0.7, 0.9, 0.97)
STEPS = (1e-4, 1e-3, 1e-2)
MODES = (("semi-implicit-euler", True), ("heun", False), ("heun", True), ("rk4", False), ("rk4", True))
OUT = Path(__file__).parent / "results" / "decay_factor.json"


def measure(scene, integrator, dt, q_off, v0, **method):
    try:
        repair = pinstab.simulate(
            scene,
            integrator=integrator,
            dt=dt,
            duration=300 * dt,
            solver="dense",
            q0=q_off,
            v0=v0,
            assemble_initial=False,
            **method,
        )
        below = np.flatnonzero(repair.position_drift <= 1e-3 * repair.position_drift[0])
        steps = int(below[0]) if below.size else None
        steady = pinstab.simulate(scene, integrator=integrator, dt=dt, duration=2.0, solver="dense", **method)
        return {"steps": steps, "floor": float(steady.position_drift.max())}
    except pinstab.PinstabError as exc:
        return {"steps": None, "floor": None, "error": type(exc).__name__}


def main() -> None:
    scene = pinstab.load_scene("fourbar")
    q_off, v0 = perturbed_start(pinstab.ConstrainedModel(scene), 0.05)
    rows = []
    for integrator, hold in MODES:
        for dt in STEPS:
            cells = {
                f"r={r}": measure(scene, integrator, dt, q_off, v0, method="mukharlyamov", decay=r, hold=hold)
                for r in DECAYS
            }
            cells["baumgarte"] = measure(scene, integrator, dt, q_off, v0, method="baumgarte")
            rows.append({"integrator": integrator, "hold": hold, "dt": dt, **cells})
            text = "  ".join(
                f"{name}: {c['steps'] if c['steps'] is not None else '-':>4} / {c['floor']:.1e}"
                if c["floor"] is not None
                else f"{name}: diverged"
                for name, c in cells.items()
            )
            label = integrator + (" held" if hold and integrator != "semi-implicit-euler" else "")
            print(f"{label:20s} dt={dt:<7g} {text}", flush=True)
    save_results(OUT, {"rows": rows})
    print(f"(steps to 1e-3 of the initial violation / max drift over 2 s) -> {OUT}")


if __name__ == "__main__":
    main()
