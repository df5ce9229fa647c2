"""Step time against mechanism size: the N-four-bar with N loops (2N + 1 bodies)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..scene import load_scene
from ..simulate import simulate

SIZES = (1, 2, 5, 10, 20, 40)
PATHS = {
    "native (no solver named)": dict(method="baumgarte", solver=None),
    "baumgarte + dense": dict(method="baumgarte", solver="dense"),
    "baumgarte + proxsuite": dict(method="baumgarte", solver="proxsuite"),
}


def step_time(n: int, method: str, solver: str | None, dt: float = 1e-3, steps: int = 200) -> float:
    """Median seconds per semi-implicit-Euler step of ``simulate()``'s stepping loop (its
    ``wall_time``, 5 runs) on nfourbar N = n."""
    scene = load_scene("nfourbar", N=n)
    rounds = []
    for _ in range(5):
        trajectory = simulate(scene, method, "semi-implicit-euler", dt, steps * dt, solver)
        rounds.append(trajectory.wall_time / steps)
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
