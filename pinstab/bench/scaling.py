"""Step time against mechanism size: the N-four-bar with N loops (2N + 1 bodies)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..assembly import assemble
from ..integrators import INTEGRATORS
from ..scene import load_scene
from ..system import build_system

SIZES = (1, 2, 5, 10, 20, 40)
PATHS = {
    "pinocchio (method)": dict(method="pinocchio", solver=None),
    "baumgarte + dense": dict(method="baumgarte", solver="dense"),
    "baumgarte + proxsuite": dict(method="baumgarte", solver="proxsuite"),
}


def step_time(n: int, method: str, solver: str | None, dt: float = 1e-3, steps: int = 200) -> float:
    """Median seconds per semi-implicit-Euler step (5 rounds) of nfourbar N = n."""
    scene = load_scene("nfourbar", N=n)
    system = build_system(scene, method, solver)
    start = assemble(system.model, scene.q0, scene.v0)
    system.stabilizer.bind(system.model, dt, "semi-implicit-euler", start.q)
    stepper = INTEGRATORS.build("semi-implicit-euler", system)
    rounds = []
    for _ in range(5):
        q, v, t = start.q.copy(), start.v.copy(), 0.0
        began = time.perf_counter()
        for _ in range(steps):
            step = stepper.step(q, v, t, dt)
            q, v, t = step.q, step.v, t + dt
        rounds.append((time.perf_counter() - began) / steps)
    return float(np.median(rounds))


def scaling(sizes: tuple[int, ...] = SIZES) -> dict[str, Any]:
    """Step times per path and N, and the exponent p of step time ~ bodies^p fitted over all sizes."""
    bodies = [2 * n + 1 for n in sizes]
    result: dict[str, Any] = {"N": list(sizes), "bodies": bodies, "step_us": {}, "exponent": {}}
    for label, options in PATHS.items():
        times = [step_time(n, **options) for n in sizes]
        result["step_us"][label] = [t * 1e6 for t in times]
        result["exponent"][label] = float(np.polyfit(np.log(bodies), np.log(times), 1)[0])
    fastest = min(PATHS, key=lambda label: result["step_us"][label][-1])
    result["fastest"] = fastest
    result["scaling_exponent"] = result["exponent"][fastest]
    return result
