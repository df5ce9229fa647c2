"""Peers run in the same process and measured the same way: Pinocchio's native constraintDynamics loop."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from ..kinematics import Kinematics
from ..scene import Scene
from ..solvers import PinocchioSolver

NativeStep = Callable[[np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]


def native_step(scene: Scene, dt: float, kp: float, kd: float) -> NativeStep:
    """One step of Pinocchio's own loop: ``a = constraintDynamics`` with its Baumgarte corrector
    (Kp [1/s^2], Kd [1/s]), then semi-implicit Euler, driven from Python as its examples do. The
    scene's force elements are applied as a Pinocchio user would: joint torques directly,
    spring-dampers through a frame kinematics pass (``computeJointJacobians`` +
    ``updateFramePlacements``) each step.

    Returns:
        ``step(q, v, t) -> (q, v)`` for a step of ``dt`` [s] from time t [s].
    """
    solver = PinocchioSolver(scene.model, scene.constraints, kp, kd)
    model, data, models, datas, settings = solver.model, solver.data, solver.models, solver.datas, solver.settings
    forces = scene.forces
    needs_kinematics = any(element.needs_kinematics for element in forces)
    kin = Kinematics(model)
    zero = np.zeros(model.nv)

    def step(q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        if needs_kinematics:
            kin.update_jacobians(q)
        tau = sum((element.generalized_force(kin, v, t) for element in forces), zero) if forces else zero
        a = pin.constraintDynamics(model, data, q, v, tau, models, datas, settings)
        v = v + dt * a
        return pin.integrate(model, q, dt * v), v

    return step


def native_pinocchio(
    scene: Scene, q0: np.ndarray, v0: np.ndarray, dt: float, steps: int, kp: float, kd: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """:func:`native_step` run for ``steps`` steps from (q0, v0).

    Returns:
        (q samples (steps+1, nq), v samples (steps+1, nv), CPU seconds of the loop).
    """
    step = native_step(scene, dt, kp, kd)
    qs, vs = np.empty((steps + 1, scene.model.nq)), np.empty((steps + 1, scene.model.nv))
    q, v = q0.copy(), v0.copy()
    qs[0], vs[0] = q, v
    start = time.process_time()
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, steps + 1):
            q, v = step(q, v, (k - 1) * dt)
            qs[k], vs[k] = q, v
    return qs, vs, time.process_time() - start
