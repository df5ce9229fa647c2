"""Peers run in the same process and measured the same way: Pinocchio's native constraintDynamics loop."""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from ..forces import JointTorque
from ..kinematics import Kinematics
from ..scene import Scene
from ..solvers import PinocchioSolver


def native_pinocchio(
    scene: Scene, q0: np.ndarray, v0: np.ndarray, dt: float, steps: int, kp: float, kd: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Pinocchio's own loop: ``a = constraintDynamics`` with its Baumgarte corrector (Kp [1/s^2], Kd
    [1/s]), semi-implicit Euler, driven from Python as its examples do. The scene's force elements
    are applied as a Pinocchio user would: joint torques directly, spring-dampers through a frame
    kinematics pass (``computeJointJacobians`` + ``updateFramePlacements``) each step.

    Returns:
        (q samples (steps+1, nq), v samples (steps+1, nv), CPU seconds of the loop).
    """
    solver = PinocchioSolver(scene.model, scene.constraints, kp, kd)
    model, data, models, datas, settings = solver.model, solver.data, solver.models, solver.datas, solver.settings
    needs_kinematics = any(not isinstance(element, JointTorque) for element in scene.forces)
    kin = Kinematics(model)
    qs, vs = np.empty((steps + 1, model.nq)), np.empty((steps + 1, model.nv))
    q, v = q0.copy(), v0.copy()
    qs[0], vs[0] = q, v
    start = time.process_time()
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, steps + 1):
            if needs_kinematics:
                kin.update_jacobians(q)
            tau = sum((element.generalized_force(kin, v, (k - 1) * dt) for element in scene.forces), np.zeros(model.nv))
            a = pin.constraintDynamics(model, data, q, v, tau, models, datas, settings)
            v = v + dt * a
            q = pin.integrate(model, q, dt * v)
            qs[k], vs[k] = q, v
    return qs, vs, time.process_time() - start
