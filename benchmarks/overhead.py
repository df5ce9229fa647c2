"""Per-step overhead: pinstab's stabilized step against Pinocchio's native constraintDynamics step,
both driven from Python, timed interleaved in one process (issue 5, item 3).

The native step is ``a = constraintDynamics(...)`` with Baumgarte Kp = 10, Kd = 2 sqrt(10), then
semi-implicit Euler (``v += dt a``, ``q = integrate(q, dt v)``). The pinstab step is one integrator
step plus the stabilizer's correction, as ``simulate`` runs it, without the per-step recording.

    python benchmarks/overhead.py          # prints the table, writes benchmarks/results/overhead.json
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

import pinstab
from pinstab.integrators import make_integrator
from pinstab.simulate import build_system
from pinstab.solvers import PinocchioSolver

SCENES = {"fourbar": {}, "nfourbar": {"N": 10}}
CONFIGURATIONS = {
    "pinocchio (method), semi-implicit-euler": dict(method="pinocchio", solver=None),
    "baumgarte + dense, semi-implicit-euler": dict(method="baumgarte", solver="dense"),
    "mukharlyamov + dense, semi-implicit-euler": dict(method="mukharlyamov", solver="dense"),
}
DT, STEPS, ROUNDS = 1e-3, 500, 7
OUT = Path(__file__).parent / "results" / "overhead.json"


def native_stepper(scene, q0, v0):
    kp, kd = 10.0, 2 * math.sqrt(10.0)
    solver = PinocchioSolver(scene.model, scene.constraints, kp, kd)
    model, data, models, datas, settings = solver.model, solver.data, solver.models, solver.datas, solver.settings
    tau = np.zeros(model.nv)

    def run(steps: int) -> None:
        q, v = q0.copy(), v0.copy()
        for _ in range(steps):
            a = pin.constraintDynamics(model, data, q, v, tau, models, datas, settings)
            v = v + DT * a
            q = pin.integrate(model, q, DT * v)

    return run


def pinstab_stepper(scene, q0, v0, method, solver):
    system = build_system(scene, method, solver)
    system.stabilizer.bind(system, DT, "semi-implicit-euler", q0)
    stepper = make_integrator("semi-implicit-euler", system)
    stabilizer = system.stabilizer

    def run(steps: int) -> None:
        q, v, t = q0.copy(), v0.copy(), 0.0
        for _ in range(steps):
            step = stepper.step(q, v, t, DT)
            t += DT
            correction = stabilizer.correct(system, step.q, step.v, t)
            q, v = correction.q, correction.v

    return run


def per_step_time(run) -> float:
    start = time.perf_counter()
    run(STEPS)
    return (time.perf_counter() - start) / STEPS


def main() -> None:
    results = {}
    for name, parameters in SCENES.items():
        scene = pinstab.load_scene(name, **parameters)
        start = pinstab.assemble(build_system(scene, "none", "dense"), scene.q0, scene.v0)
        native = native_stepper(scene, start.q, start.v)
        candidates = {
            label: pinstab_stepper(scene, start.q, start.v, **options) for label, options in CONFIGURATIONS.items()
        }
        timings = {label: [] for label in ["native", *candidates]}
        for _ in range(ROUNDS):  # interleaved: every round times every stepper once
            timings["native"].append(per_step_time(native))
            for label, run in candidates.items():
                timings[label].append(per_step_time(run))
        best = {label: float(np.median(values)) for label, values in timings.items()}
        ratios = {label: best[label] / best["native"] for label in candidates}
        fastest = min(ratios, key=ratios.get)
        results[name] = {
            "native_us": best["native"] * 1e6,
            "step_us": {label: best[label] * 1e6 for label in candidates},
            "ratios": ratios,
            "fastest": fastest,
            "overhead_ratio": ratios[fastest],
        }
        print(f"{name}: native {best['native'] * 1e6:.1f} us/step")
        for label in candidates:
            print(f"  {label:45s} {best[label] * 1e6:8.1f} us/step  ratio {ratios[label]:6.1f}")
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text(json.dumps(results, indent=1))
    print(f"-> {OUT}")


if __name__ == "__main__":
    main()
