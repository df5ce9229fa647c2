"""Peers run in the same process and measured the same way: a hand-written loop over Pinocchio's
``constraintDynamics`` (semi-implicit Euler or RK4)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from ..errors import PinstabError
from ..kinematics import Kinematics
from ..paths.native import NativeDynamics
from ..scene import Scene

NativeStep = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]


PEER_SCHEMES = ("semi-implicit-euler", "rk4")  # the work-precision sweeps' hand-written loops
STEP_SCHEMES = ("euler", "semi-implicit-euler", "heun", "rk4")  # every fixed-step scheme a loop is written for


def native_acceleration(scene: Scene, kp: float, kd: float) -> Callable[[np.ndarray, np.ndarray, float], np.ndarray]:
    """``a(q, v, t)`` [rad/s^2, m/s^2] as a Pinocchio user writes it: ``pin.constraintDynamics`` with its
    Baumgarte corrector (Kp [1/s^2], Kd [1/s]; 0 and 0 for the bare index-1 equations), the scene's force
    elements applied as joint torques directly, spring-dampers through a frame kinematics pass
    (``computeJointJacobians`` + ``updateFramePlacements``) each evaluation."""
    native = NativeDynamics(scene.model, scene.constraints, kp, kd)
    model, data, models, datas, settings = native.model, native.data, native.models, native.datas, native.settings
    forces = scene.forces
    needs_kinematics = any(element.needs_kinematics for element in forces)
    kin = Kinematics(model)
    zero = np.zeros(model.nv)
    dynamics = pin.constraintDynamics

    def acceleration(q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        if not forces:
            return dynamics(model, data, q, v, zero, models, datas, settings)
        if needs_kinematics:
            kin.update_jacobians(q)
        tau = sum((element.generalized_force(kin, v, t) for element in forces), zero)
        return dynamics(model, data, q, v, tau, models, datas, settings)

    return acceleration


def native_step(scene: Scene, dt: float, kp: float, kd: float, scheme: str = "semi-implicit-euler") -> NativeStep:
    """One step of a hand-written loop over Pinocchio: ``a =`` :func:`native_acceleration` (Kp [1/s^2],
    Kd [1/s]), then explicit or semi-implicit Euler, Heun or classical RK4 with ``pin.integrate``.

    Returns:
        ``step(q, v, t) -> (q, v)`` for a step of ``dt`` [s] from time t [s].

    Raises:
        PinstabError: an unknown scheme.
    """
    if scheme not in STEP_SCHEMES:
        raise PinstabError(f"unknown peer scheme {scheme!r}; schemes: {', '.join(STEP_SCHEMES)}")
    model = scene.model
    acceleration = native_acceleration(scene, kp, kd)
    integrate = pin.integrate

    def semi_implicit_step(q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        v = v + dt * acceleration(q, v, t)
        return integrate(model, q, dt * v), v

    def euler_step(q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        return integrate(model, q, dt * v), v + dt * acceleration(q, v, t)

    half, sixth = 0.5 * dt, dt / 6.0

    def heun_step(q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        a1 = acceleration(q, v, t)
        v2 = v + dt * a1
        a2 = acceleration(integrate(model, q, dt * v), v2, t + dt)
        return integrate(model, q, half * (v + v2)), v + half * (a1 + a2)

    def rk4_step(q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        a1 = acceleration(q, v, t)
        v2 = v + half * a1
        a2 = acceleration(integrate(model, q, half * v), v2, t + half)
        v3 = v + half * a2
        a3 = acceleration(integrate(model, q, half * v2), v3, t + half)
        v4 = v + dt * a3
        a4 = acceleration(integrate(model, q, dt * v3), v4, t + dt)
        return integrate(model, q, sixth * (v + 2.0 * (v2 + v3) + v4)), v + sixth * (a1 + 2.0 * (a2 + a3) + a4)

    steps = {"euler": euler_step, "semi-implicit-euler": semi_implicit_step, "heun": heun_step, "rk4": rk4_step}
    return steps[scheme]


def native_pinocchio(
    scene: Scene,
    q0: np.ndarray,
    v0: np.ndarray,
    dt: float,
    steps: int,
    kp: float,
    kd: float,
    scheme: str = "semi-implicit-euler",
) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`native_step` run for ``steps`` steps from (q0, v0), storing q and v every step.

    Returns:
        (q samples (steps+1, nq), v samples (steps+1, nv), CPU seconds of the loop).
    """
    step = native_step(scene, dt, kp, kd, scheme)
    qs, vs = np.empty((steps + 1, scene.model.nq)), np.empty((steps + 1, scene.model.nv))
    q, v = q0.copy(), v0.copy()
    qs[0], vs[0] = q, v
    start = time.process_time()
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, steps + 1):
            q, v = step(q, v, (k - 1) * dt)
            qs[k], vs[k] = q, v
    return qs, vs, time.process_time() - start
