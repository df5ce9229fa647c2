"""The N-four-bar's exact motion: its cranks stay parallel and its couplers level, so the mechanism is one
pendulum in the crank angle th (from the vertical), J th'' = K sin th with J = (N + 1) m L^2 / 3 + N m L^2
and K = m g L ((N + 1) / 2 + N); crank joints at th, coupler joints at -th."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..errors import PinstabError
from ..scene import Scene
from .references import EXACT_REFERENCES, EXACT_TOLERANCE, Reference, solve_exact

START_TOLERANCE = 1e-9  # [rad, rad/s] a start this far from the parallelogram branch is refused


@EXACT_REFERENCES.register("nfourbar", summary="the parallelogram pendulum J th'' = K sin th")
def parallelogram_motion(scene: Scene, q0: np.ndarray, v0: np.ndarray, times: np.ndarray) -> Reference:
    """The N-four-bar's motion from (q0, v0) at ``times`` [s]: the pendulum ODE integrated by SciPy's DOP853
    at 1e-13.

    Raises:
        PinstabError: gravity not along -y, or a start off the parallelogram branch (cranks not parallel,
            couplers not level), naming the joint.
    """
    model = scene.model
    n = int(scene.parameters.get("N", (model.njoints - 1) // 2))
    length = float(scene.parameters.get("link_length", 1.0))
    mass = float(scene.parameters.get("link_mass", 1.0))
    gravity = model.gravity.linear
    if not (gravity[1] < 0 and np.allclose(gravity[[0, 2]], 0.0)):
        raise PinstabError(f"nfourbar's exact reference assumes gravity along -y; the scene's is {list(gravity)}")
    cranks = [_index(model, f"crank{k}_joint") for k in range(n + 1)]
    couplers = [_index(model, f"coupler{k}_joint") for k in range(1, n + 1)]
    theta, rate = float(q0[cranks[0]]), float(v0[cranks[0]])
    for indices, sign in ((cranks, 1.0), (couplers, -1.0)):
        for index in indices:
            off = max(abs(q0[index] - sign * theta), abs(v0[index] - sign * rate))
            if off > START_TOLERANCE:
                raise PinstabError(
                    f"nfourbar's exact reference holds on the parallelogram branch (cranks at crank0's angle, "
                    f"couplers at minus it); joint {model.names[_joint(model, index)]!r} starts {off:.3g} off it"
                )
    inertia = (n + 1) * mass * length**2 / 3 + n * mass * length**2
    stiffness = mass * float(-gravity[1]) * length * ((n + 1) / 2 + n) / inertia

    def slope(_: float, state: np.ndarray) -> np.ndarray:
        return np.array([state[1], stiffness * math.sin(state[0])])

    angles = solve_exact(slope, np.array([theta, rate]), times)[:, 0]
    q = np.tile(pin.neutral(model), (len(times), 1))
    q[:, cranks] = angles[:, None]
    q[:, couplers] = -angles[:, None]
    kind = f"exact: the parallelogram pendulum, N = {n} (SciPy DOP853, rtol = atol = {EXACT_TOLERANCE:g})"
    return Reference(kind, q, ("crank0_joint",))


def _index(model: pin.Model, joint: str) -> int:
    if not model.existJointName(joint):
        raise PinstabError(f"nfourbar's exact reference needs joint {joint!r}, which the scene's model lacks")
    return model.joints[model.getJointId(joint)].idx_q


def _joint(model: pin.Model, index: int) -> int:
    return next(j for j in range(1, model.njoints) if model.joints[j].idx_q == index)
