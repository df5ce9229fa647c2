"""SciPy's DOP853 over Pinocchio: the peer a numerical analyst reaches for. ``solve_ivp`` integrates
y = (q, v), y' = (v, a) with a = ``pin.constraintDynamics`` (Baumgarte corrector Kp, Kd; Kp = Kd = 0 is the
bare index-1 equation whose drift is the integration error alone), the error controlled to rtol = atol,
samples at the output times from its dense output."""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import PinstabError
from ..scene import Scene
from .peers import native_acceleration

SCIPY_PEER = "scipy-dop853"


def run_scipy(
    scene: Scene, q0: np.ndarray, v0: np.ndarray, dt: float, steps: int, kp: float, kd: float, rtol: float
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """DOP853 from (q0, v0) to ``steps * dt`` [s], sampled every ``dt`` [s], at rtol = atol = ``rtol``.

    Returns:
        (q samples (steps+1, nq), v samples (steps+1, nv), CPU seconds of ``solve_ivp``, dynamics evaluations).

    Raises:
        PinstabError: a model whose configuration is not its coordinates' sum (free flyers, spherical or
            continuous joints: q' = v does not hold there), or the integration failed (SciPy's message).
    """
    model = scene.model
    if model.nq != model.nv or any(model.joints[j].nq != 1 for j in range(1, model.njoints)):
        raise PinstabError(
            f"the SciPy peer integrates q' = v: scene {scene.name!r} has joints with nq != nv (free flyers, "
            "spherical or continuous joints)"
        )
    nq = model.nq
    acceleration = native_acceleration(scene, kp, kd)

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        return np.concatenate((y[nq:], acceleration(y[:nq], y[nq:], t)))

    times = np.arange(steps + 1) * dt
    start = time.process_time()
    with np.errstate(over="ignore", invalid="ignore"):
        solution = solve_ivp(
            rate, (0.0, times[-1]), np.concatenate((q0, v0)), method="DOP853", t_eval=times, rtol=rtol, atol=rtol
        )
    cpu = time.process_time() - start
    if not solution.success:
        raise PinstabError(f"SciPy's DOP853 failed: {solution.message}")
    return solution.y[:nq].T, solution.y[nq:].T, cpu, int(solution.nfev)
