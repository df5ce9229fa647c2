"""Per-step overhead: pinstab's stabilized step against Pinocchio's native step, both driven from
Python and timed interleaved in one process."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ..assembly import assemble
from ..integrators import INTEGRATORS
from ..model import ConstrainedModel
from ..scene import Scene
from ..system import build_system
from .peers import native_step

CANDIDATES = {
    "pinocchio (method), semi-implicit-euler": dict(method="pinocchio", solver=None),
    "baumgarte + dense, semi-implicit-euler": dict(method="baumgarte", solver="dense"),
    "mukharlyamov + dense, semi-implicit-euler": dict(method="mukharlyamov", solver="dense"),
}


def _native(scene: Scene, q0, v0, dt):
    step = native_step(scene, dt, 10.0, 2 * math.sqrt(10.0))

    def run(steps: int) -> None:
        q, v, t = q0.copy(), v0.copy(), 0.0
        for _ in range(steps):
            q, v = step(q, v, t)
            t += dt

    return run


def _pinstab(scene: Scene, q0, v0, dt, method, solver):
    system = build_system(scene, method, solver)
    model = system.model
    system.stabilizer.bind(model, dt, "semi-implicit-euler", q0)
    stepper = INTEGRATORS.build("semi-implicit-euler", system)
    stabilizer = system.stabilizer

    def run(steps: int) -> None:
        q, v, t = q0.copy(), v0.copy(), 0.0
        for _ in range(steps):
            step = stepper.step(q, v, t, dt)
            t += dt
            correction = stabilizer.correct(model, step.q, step.v, t)
            q, v = correction.q, correction.v

    return run


def measure_overhead(scene: Scene, dt: float = 1e-3, steps: int = 500, rounds: int = 7) -> dict[str, Any]:
    """Median seconds per step of the native loop (with the scene's forces) and of each pinstab
    candidate (one integrator step plus the stabilizer's correction, as ``simulate`` runs it, without
    its per-step recording), timed interleaved; ``overhead_ratio`` is the fastest candidate over
    native."""
    start = assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    runners = {"native": _native(scene, start.q, start.v, dt)}
    runners.update({label: _pinstab(scene, start.q, start.v, dt, **options) for label, options in CANDIDATES.items()})
    timings: dict[str, list[float]] = {label: [] for label in runners}
    for _ in range(rounds):
        for label, run in runners.items():
            began = time.perf_counter()
            run(steps)
            timings[label].append((time.perf_counter() - began) / steps)
    best = {label: float(np.median(values)) for label, values in timings.items()}
    ratios = {label: best[label] / best["native"] for label in CANDIDATES}
    fastest = min(ratios, key=ratios.get)
    return {
        "native_us": best["native"] * 1e6,
        "step_us": {label: best[label] * 1e6 for label in CANDIDATES},
        "ratios": ratios,
        "fastest": fastest,
        "overhead_ratio": ratios[fastest],
    }
