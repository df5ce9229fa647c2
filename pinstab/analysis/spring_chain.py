"""An independent reference for an open chain held by spring-dampers (``stiff-fourbar``): SciPy's ``Radau`` on the
chain's ODE, written with Pinocchio alone.

The state is (q, v, W), W the work the dampers have dissipated [J]:

    q' = v,   v' = ABA(q, v, tau),   W' = sum_i c_i (dL_i/dt)^2,
    tau = sum_i (J_a - J_b)^T F_i,   F_i = -(k_i (L_i - L0_i) + c_i dL_i/dt) u_i,   u_i = (p_a - p_b) / L_i,

with p and J the points' world positions and LOCAL_WORLD_ALIGNED linear Jacobians (``pin.forwardKinematics``,
``pin.computeJointJacobians``, ``pin.getFrameJacobian``). Neither pinstab's compiled spring law nor its integrators
are used: the joints must have nq = nv (revolute, prismatic). Its check: the mechanical energy plus W stays
constant (:meth:`SpringChain.energy`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..errors import PinstabError
from ..forces.spring_damper import SpringDamper
from ..scene import Scene
from .references import EXACT_REFERENCES, Reference, solve_exact

RADAU_TOLERANCE = 1e-12  # rtol = atol of the reference's Radau run
JACOBIAN_STEP = 1e-7  # relative step of the Newton Jacobian's central differences (only Newton's speed rides on it)
COINCIDENT_LENGTH = 1e-12  # [m] a spring shorter than this has no direction: the reference refuses the state


@dataclass(frozen=True)
class Spring:
    """A linear spring-damper between a point on joint a's body and one on joint b's (joint 0: the world).

    Attributes:
        name: its name (in messages).
        joint_a, joint_b: the bodies' joint indices. placement_a, placement_b: the points in their joint frames [m].
        stiffness: k [N/m]. damping: c [N s/m]. rest_length: L0 [m].
    """

    name: str
    joint_a: int
    placement_a: pin.SE3
    joint_b: int
    placement_b: pin.SE3
    stiffness: float
    damping: float
    rest_length: float

    @classmethod
    def of(cls, model: pin.Model, element: SpringDamper) -> Spring:
        """The spring of a scene's ``spring-damper`` element, its points read from ``model``'s frames."""
        frame_a = model.frames[element.frame_a]
        if element.frame_b is None:
            joint_b, placement_b = 0, pin.SE3(np.eye(3), element.world_point_b)
        else:
            frame_b = model.frames[element.frame_b]
            joint_b, placement_b = frame_b.parentJoint, frame_b.placement
        return cls(
            element.name,
            frame_a.parentJoint,
            frame_a.placement,
            joint_b,
            placement_b,
            element.stiffness,
            element.damping,
            element.rest_length,
        )


class SpringChain:
    """An open chain's ODE with spring-dampers, evaluated by Pinocchio (see the module's docstring).

    Args:
        model: the chain (gravity included; every joint nq = nv).
        springs: its spring-dampers.

    Raises:
        PinstabError: a joint with nq != nv.
    """

    def __init__(self, model: pin.Model, springs: list[Spring]) -> None:
        if model.nq != model.nv:
            raise PinstabError(
                f"the spring-chain reference needs joints with nq = nv (revolute, prismatic); the model has "
                f"nq = {model.nq}, nv = {model.nv}"
            )
        self.model, self.data, self.springs = model, model.createData(), springs

    def _point(self, joint: int, placement: pin.SE3) -> tuple[np.ndarray, np.ndarray]:
        if joint == 0:
            return placement.translation.copy(), np.zeros((3, self.model.nv))
        position = self.data.oMi[joint].act(placement.translation)
        jacobian = pin.getFrameJacobian(self.model, self.data, joint, placement, pin.LOCAL_WORLD_ALIGNED)[:3]
        return position, jacobian

    def lines(self, q: np.ndarray, v: np.ndarray) -> list[tuple[float, float, np.ndarray]]:
        """Each spring's length L [m], rate dL/dt [m/s] and J^T u (nv,) [m/rad] at (q, v).

        Raises:
            PinstabError: a spring's points coincide (its direction is undefined).
        """
        pin.forwardKinematics(self.model, self.data, q)
        pin.computeJointJacobians(self.model, self.data, q)
        result = []
        for spring in self.springs:
            p_a, j_a = self._point(spring.joint_a, spring.placement_a)
            p_b, j_b = self._point(spring.joint_b, spring.placement_b)
            length = float(np.linalg.norm(p_a - p_b))
            if length < COINCIDENT_LENGTH:
                raise PinstabError(
                    f"spring {spring.name!r}: its points coincide (length {length:.3g} m), where its direction is "
                    "not defined; start the reference with them apart"
                )
            lever = (j_a - j_b).T @ ((p_a - p_b) / length)
            result.append((length, float(lever @ v), lever))
        return result

    def rate(self, _: float, state: np.ndarray) -> np.ndarray:
        """d/dt of the state (q, v, W) [rad, rad/s, J]."""
        nv = self.model.nv
        q, v = state[:nv], state[nv : 2 * nv]
        tau = np.zeros(nv)
        dissipation = 0.0
        for spring, (length, length_rate, lever) in zip(self.springs, self.lines(q, v), strict=True):
            tau -= (spring.stiffness * (length - spring.rest_length) + spring.damping * length_rate) * lever
            dissipation += spring.damping * length_rate**2
        acceleration = pin.aba(self.model, self.data, q, v, tau)
        return np.concatenate([v, acceleration, [dissipation]])

    def jacobian(self, t: float, state: np.ndarray) -> np.ndarray:
        """d rate / d state by central differences in q and v (steps 1e-7 (1 + |y_i|)); nothing depends on W, whose
        column is zero (SciPy's own differences would grow its step there until it overflows)."""
        result = np.zeros((len(state), len(state)))
        for i in range(len(state) - 1):
            step = np.zeros(len(state))
            step[i] = JACOBIAN_STEP * (1.0 + abs(state[i]))
            result[:, i] = (self.rate(t, state + step) - self.rate(t, state - step)) / (2 * step[i])
        return result

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """Kinetic + gravity potential + the springs' k (L - L0)^2 / 2 [J] at (q, v)."""
        kinetic = pin.computeKineticEnergy(self.model, self.data, q, v)
        gravity = pin.computePotentialEnergy(self.model, self.data, q)
        springs = sum(
            0.5 * spring.stiffness * (length - spring.rest_length) ** 2
            for spring, (length, _, _) in zip(self.springs, self.lines(q, v), strict=True)
        )
        return float(kinetic + gravity + springs)

    def solve(
        self, q0: np.ndarray, v0: np.ndarray, times: np.ndarray, tolerance: float = RADAU_TOLERANCE
    ) -> np.ndarray:
        """The states (q, v, W) at ``times`` [s] from (q0, v0) at times[0], by SciPy's ``Radau`` at rtol = atol =
        ``tolerance`` (its Jacobian: :meth:`jacobian`); (len(times), 2 nv + 1).

        Raises:
            PinstabError: the integration failed (SciPy's message).
        """
        start = np.concatenate([q0, v0, [0.0]])
        return solve_exact(self.rate, start, times, method="Radau", tolerance=tolerance, jacobian=self.jacobian)


def scene_chain(scene: Scene) -> SpringChain:
    """The chain of a scene without constraints whose force elements are all ``spring-damper``s.

    Raises:
        PinstabError: the scene has constraints or another kind of force element (naming it).
    """
    if scene.constraints:
        raise PinstabError(f"the spring-chain reference needs an open chain; {scene.name!r} has constraints")
    for element in scene.forces:
        if not isinstance(element, SpringDamper):
            raise PinstabError(
                f"the spring-chain reference takes spring-damper forces only; {element.name!r} is "
                f"{type(element).__name__}"
            )
    return SpringChain(scene.model, [Spring.of(scene.model, element) for element in scene.forces])


@EXACT_REFERENCES.register("stiff-fourbar", summary="SciPy Radau on the open chain's ODE (Pinocchio ABA + springs)")
def spring_chain_motion(scene: Scene, q0: np.ndarray, v0: np.ndarray, times: np.ndarray) -> Reference:
    """The chain's motion from (q0, v0) at ``times`` [s] by SciPy's Radau at rtol = atol = 1e-12.

    Raises:
        PinstabError: see :func:`scene_chain`, :meth:`SpringChain.solve`.
    """
    chain = scene_chain(scene)
    kind = f"SciPy Radau on the open chain's ODE (Pinocchio ABA), rtol = atol = {RADAU_TOLERANCE:g}"
    return Reference(kind, chain.solve(q0, v0, times)[:, : scene.model.nq], tuple(scene.model.names[1:]))
