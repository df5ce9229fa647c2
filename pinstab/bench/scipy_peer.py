"""SciPy's integrators over Pinocchio: the peers a numerical analyst reaches for. ``solve_ivp`` integrates
y = (q, v), y' = (v, a) with a = ``pin.constraintDynamics`` and the scene's force elements
(:func:`~pinstab.bench.peers.native_acceleration`; Baumgarte corrector Kp, Kd; Kp = Kd = 0 is the bare index-1
equation whose drift is the integration error alone), the error controlled to rtol = atol, samples at the output
times from its dense output.

The methods (:data:`SCIPY_METHODS`): ``DOP853`` (explicit, order 8) and the implicit ``Radau`` (Radau IIA, order 5)
and ``BDF`` (orders 1-5). The implicit ones get the Jacobian d y'/d y as a numerical analyst writes it for this
system (``jac=``): the rows of q' = v exactly ([0, I]), the acceleration's rows by central differences in q and v
(steps 1e-7 (1 + |y_i|), 4 nv evaluations of a, counted in the evaluations). SciPy evaluates it again only when
its Newton iterations converge slowly.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import PinstabError, choices
from ..scene import Scene
from .peers import native_acceleration

SCIPY_METHODS = {"scipy-dop853": "DOP853", "scipy-radau": "Radau", "scipy-bdf": "BDF"}
"""The SciPy peers by name: their ``solve_ivp`` method."""
SCIPY_PEER = "scipy-dop853"  # the explicit one
IMPLICIT_SCIPY_PEERS = ("scipy-radau", "scipy-bdf")
JACOBIAN_STEP = 1e-7  # relative step of the acceleration's central differences


def run_scipy(
    scene: Scene,
    q0: np.ndarray,
    v0: np.ndarray,
    dt: float,
    steps: int,
    kp: float,
    kd: float,
    rtol: float,
    peer: str = SCIPY_PEER,
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """SciPy's ``peer`` method from (q0, v0) to ``steps * dt`` [s], sampled every ``dt`` [s], at rtol = atol =
    ``rtol``, Baumgarte gains Kp [1/s^2], Kd [1/s].

    Returns:
        (q samples (steps+1, nq), v samples (steps+1, nv), CPU seconds of ``solve_ivp``, dynamics evaluations
        (the right-hand side's and the Jacobian's)).

    Raises:
        PinstabError: an unknown peer, a model whose configuration is not its coordinates' sum (free flyers,
            spherical or continuous joints: q' = v does not hold there), or the integration failed (SciPy's
            message).
    """
    if peer not in SCIPY_METHODS:
        raise PinstabError(f"unknown SciPy peer {peer!r}; peers: {choices(SCIPY_METHODS)}")
    method = SCIPY_METHODS[peer]
    model = scene.model
    if model.nq != model.nv or any(model.joints[j].nq != 1 for j in range(1, model.njoints)):
        raise PinstabError(
            f"the SciPy peer integrates q' = v: scene {scene.name!r} has joints with nq != nv (free flyers, "
            "spherical or continuous joints)"
        )
    nq = model.nq
    acceleration = native_acceleration(scene, kp, kd)
    jacobian_calls = [0]

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        return np.concatenate((y[nq:], acceleration(y[:nq], y[nq:], t)))

    def jacobian(t: float, y: np.ndarray) -> np.ndarray:
        jacobian_calls[0] += 1
        result = np.zeros((2 * nq, 2 * nq))
        result[:nq, nq:] = np.eye(nq)
        for i in range(2 * nq):
            step = np.zeros(2 * nq)
            step[i] = JACOBIAN_STEP * (1.0 + abs(y[i]))
            ahead, behind = y + step, y - step
            difference = acceleration(ahead[:nq], ahead[nq:], t) - acceleration(behind[:nq], behind[nq:], t)
            result[nq:, i] = difference / (2.0 * step[i])
        return result

    times = np.arange(steps + 1) * dt
    implicit = {} if method == "DOP853" else {"jac": jacobian}
    start = time.process_time()
    with np.errstate(over="ignore", invalid="ignore"):
        solution = solve_ivp(
            rate,
            (0.0, times[-1]),
            np.concatenate((q0, v0)),
            method=method,
            t_eval=times,
            rtol=rtol,
            atol=rtol,
            **implicit,
        )
    cpu = time.process_time() - start
    if not solution.success:
        raise PinstabError(f"SciPy's {method} failed: {solution.message}")
    return solution.y[:nq].T, solution.y[nq:].T, cpu, int(solution.nfev) + 4 * nq * jacobian_calls[0]
