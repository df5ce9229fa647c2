"""Step time against mechanism size: the N-four-bar with N loops (2N + 1 bodies)."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pinocchio as pin

from ..constraints import FrameClosure
from ..paths.banded import BandedDynamics
from ..paths.native import NativeDynamics
from ..scene import Scene, load_scene
from ..simulate import simulate
from .mujoco_peer import DEFAULT_SOLREF, run_mujoco
from .overhead import KD, KP

SIZES = (1, 2, 5, 10, 20, 40)
PATHS = {
    "native (no solver named)": dict(method="baumgarte", solver=None),
    "baumgarte + dense": dict(method="baumgarte", solver="dense"),
    "baumgarte + proxsuite": dict(method="baumgarte", solver="proxsuite"),
}


def step_time(n: int, method: str, solver: str | None, dt: float = 1e-3, steps: int = 200) -> float:
    """Median seconds per semi-implicit-Euler step of ``simulate()``'s stepping loop (its
    ``info.timings["stepping_s"]``, 5 runs) on nfourbar N = n."""
    scene = load_scene("nfourbar", N=n)
    rounds = []
    for _ in range(5):
        trajectory = simulate(scene, method, "semi-implicit-euler", dt, steps * dt, solver)
        rounds.append(trajectory.info.timings["stepping_s"] / steps)
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


CHAIN_SIZES = (10, 20, 40, 80)
LONG = 5  # the long default run lasts this many times the duration


def _evaluation_us(call, repeats: int = 100) -> float:
    """CPU microseconds of one ``call()``, mean of ``repeats``."""
    began = time.process_time()
    for _ in range(repeats):
        call()
    return (time.process_time() - began) / repeats * 1e6


def chain_costs(
    sizes: tuple[int, ...] = CHAIN_SIZES, dt: float = 1e-3, duration: float = 1.0, rounds: int = 3
) -> dict[str, Any]:
    """CPU microseconds per RK4 step of dt [s] on nfourbar N, best of ``rounds`` interleaved rounds: pinstab's
    default run (the whole ``simulate()`` call over ``duration`` [s], set-up included), the same over :data:`LONG`
    times the duration (the set-up spread over more steps, as MuJoCo's loop is timed without compiling its
    model; singular passages in proportion), the same run on Pinocchio's solve
    (``solver="pinocchio"``: the native path) and MuJoCo's RK4 ``mj_step`` (loops as ``connect``
    equalities); per evaluation, the banded solve, ``pin.constraintDynamics``, Pinocchio's ``crba`` in the world
    convention and ``nonLinearEffects`` called from Python (the banded solve forms its bias by its own pass), and
    the passage watch's sample sigma_r / sigma_1 on the banded path. Exponents p of cost ~ N^p fitted over ``sizes``."""
    steps = round(duration / dt)
    runs = ("default", "long", "native", "mujoco")
    passes = ("banded", "constraintDynamics", "pinocchio_passes", "conditioning")
    best: dict[str, dict[int, float]] = {name: {n: math.inf for n in sizes} for name in runs + passes}
    paths: dict[int, str] = {}
    for _ in range(rounds):
        for n in sizes:
            scene = load_scene("nfourbar", N=n)
            for name, solver, length in (("default", None, 1), ("long", None, LONG), ("native", "pinocchio", 1)):
                began = time.process_time()
                trajectory = simulate(scene, "baumgarte", "rk4", dt, length * duration, solver)
                best[name][n] = min(best[name][n], (time.process_time() - began) / (length * steps) * 1e6)
                paths[n] = trajectory.info.path if name == "default" else paths.get(n, "")
            _, _, seconds = run_mujoco(scene, trajectory.q[0], trajectory.v[0], dt, steps, "rk4", DEFAULT_SOLREF, steps)
            best["mujoco"][n] = min(best["mujoco"][n], seconds / steps * 1e6)
            for name, cost in _evaluations(scene, trajectory.q[-1], trajectory.v[-1]).items():
                best[name][n] = min(best[name][n], cost)
    result: dict[str, Any] = {"N": list(sizes), "dt": dt, "duration": duration, "rounds": rounds, "default_path": paths}
    for name in runs + passes:
        costs = [best[name][n] for n in sizes]
        result[name + "_us"] = costs
        result[name + "_exponent"] = float(np.polyfit(np.log(sizes), np.log(costs), 1)[0])
    result["default_over_mujoco"] = [d / m for d, m in zip(result["default_us"], result["mujoco_us"], strict=True)]
    result["long_over_mujoco"] = [d / m for d, m in zip(result["long_us"], result["mujoco_us"], strict=True)]
    result["native_over_default"] = [n / d for n, d in zip(result["native_us"], result["default_us"], strict=True)]
    return result


def _evaluations(scene: Scene, q: np.ndarray, v: np.ndarray) -> dict[str, float]:
    """CPU microseconds of one dynamics evaluation at (q, v): the banded solve, Pinocchio's
    ``constraintDynamics`` (same closures and gains), Pinocchio's ``crba`` (world convention) and
    ``nonLinearEffects`` from Python; and the banded conditioning sample, repeated at the
    one state (its iterations warm-started: the run's samples, a few steps apart, take a few more)."""
    closures = [c for c in scene.constraints if isinstance(c, FrameClosure)]
    model, tau = scene.model, np.zeros(scene.model.nv)
    banded = BandedDynamics(model, closures, KP, KD)
    native = NativeDynamics(model, closures, KP, KD)
    data = pin.Data(model)

    def passes() -> None:
        pin.crba(model, data, q, pin.Convention.WORLD)
        pin.nonLinearEffects(model, data, q, v)

    return {
        "banded": _evaluation_us(lambda: banded.acceleration(q, v, tau)),
        "constraintDynamics": _evaluation_us(lambda: native.acceleration(q, v, tau)),
        "pinocchio_passes": _evaluation_us(passes),
        "conditioning": _evaluation_us(lambda: banded.relative_singular_value(q, banded.rows)),
    }
