"""What ``simulate()`` costs over a hand-written loop of Pinocchio calls: the same scheme, step and
gains, both storing q and v every step, timed interleaved in one process (CPU time)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..assembly import assemble
from ..model import ConstrainedModel
from ..scene import Scene
from ..simulate import simulate
from .peers import STEP_SCHEMES, native_pinocchio

KP, KD = 100.0, 20.0  # [1/s^2], [1/s]: pinstab's default Baumgarte gains, given to both


def measure_overhead(scene: Scene, dt: float = 1e-3, duration: float = 2.0, rounds: int = 5) -> dict[str, Any]:
    """CPU seconds of ``simulate(scene, "baumgarte", scheme, dt, duration)`` (default recording, the
    whole call: set-up, assembly and stepping) and of the hand-written loop from the assembled start,
    for every fixed-step scheme (explicit and semi-implicit Euler, Heun, RK4), median of ``rounds``
    interleaved rounds.

    Returns:
        per scheme the microseconds per step of each and their ratio; ``overhead_ratio``: the larger
        ratio, ``path``: the path ``simulate`` took.
    """
    start = assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    steps = round(duration / dt)
    result: dict[str, Any] = {"dt": dt, "duration": duration, "steps": steps, "kp": KP, "kd": KD, "schemes": {}}
    for scheme in STEP_SCHEMES:
        hand, ours = [], []
        path = ""
        for _ in range(rounds):
            began = time.process_time()
            native_pinocchio(scene, start.q, start.v, dt, steps, KP, KD, scheme)
            hand.append(time.process_time() - began)
            began = time.process_time()
            trajectory = simulate(scene, "baumgarte", scheme, dt, duration, contacts="held", kp=KP, kd=KD)
            ours.append(time.process_time() - began)
            path = trajectory.info.path
        hand_s, ours_s = float(np.median(hand)), float(np.median(ours))
        result["schemes"][scheme] = {
            "hand_written_us": hand_s / steps * 1e6,
            "simulate_us": ours_s / steps * 1e6,
            "ratio": ours_s / hand_s,
            "path": path,
        }
    result["overhead_ratio"] = max(entry["ratio"] for entry in result["schemes"].values())
    return result
