"""Explicit integrators on the configuration Lie group: ``euler``, ``semi-implicit-euler``, ``heun``, ``rk4``,
``dop853``.

Positions advance with ``pin.integrate`` (plain addition on models whose joints all have one
coordinate). For the Runge-Kutta schemes every stage velocity is carried back to the tangent space at
the step's start point with ``pin.dDifference`` (exact ``dexp^-1``, Runge-Kutta-Munthe-Kaas), which
is the identity on models made of 1-DOF joints.

A step calls ``system.acceleration(q, v, t, stage)``: Pinocchio's own algorithm on the native path,
pinstab's KKT solve on the general one (:mod:`pinstab.system`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..registry import NoOptions, Registry
from ..stability import register_polynomial
from . import tableaus

if TYPE_CHECKING:
    from ..system import ConstrainedSystem


class Integrator:
    """One explicit step of ``dq/dt = v``, ``dv/dt = a(q, v, t)``.

    Args:
        system: the stepping system (its ``acceleration`` and its model's group operations).
        options: the integrator's options (none for the built-in schemes).

    Attributes:
        stages: acceleration evaluations per step.
    """

    name = ""
    stages = 1

    def __init__(self, system: ConstrainedSystem, options: NoOptions | None = None) -> None:
        self.system = system
        model = system.model
        self.integrate = np.add if model.euclidean else model.integrate  # the same sum, without a call layer
        self.tangent = None if model.flat else model.to_start_tangent

    def step(self, q: np.ndarray, v: np.ndarray, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """One step of ``dt`` [s] from (q, v) at time t [s]; returns the end state (q, v)."""
        raise NotImplementedError

    def slope(self, q: np.ndarray, q_stage: np.ndarray, v_stage: np.ndarray) -> np.ndarray:
        """A stage velocity as a slope in the tangent space at the step's start q."""
        return v_stage if self.tangent is None else self.tangent(q, q_stage, v_stage)


class Euler(Integrator):
    """Explicit Euler: q+ = q (+) dt v, v+ = v + dt a(q, v). Order 1."""

    name = "euler"

    def step(self, q, v, t, dt):
        return self.integrate(q, dt * v), v + dt * self.system.acceleration(q, v, t, 0)


class SemiImplicitEuler(Integrator):
    """Symplectic Euler, velocity first: v+ = v + dt a(q, v), q+ = q (+) dt v+. Order 1."""

    name = "semi-implicit-euler"

    def step(self, q, v, t, dt):
        v_new = v + dt * self.system.acceleration(q, v, t, 0)
        return self.integrate(q, dt * v_new), v_new


class Heun(Integrator):
    """Heun's two-stage Runge-Kutta method. Order 2."""

    name = "heun"
    stages = 2

    def step(self, q, v, t, dt):
        acceleration = self.system.acceleration
        a1 = acceleration(q, v, t, 0)
        q2, v2 = self.integrate(q, dt * v), v + dt * a1
        a2 = acceleration(q2, v2, t + dt, 1)
        half = 0.5 * dt
        return self.integrate(q, half * (v + self.slope(q, q2, v2))), v + half * (a1 + a2)


class RK4(Integrator):
    """Classical four-stage Runge-Kutta. Order 4."""

    name = "rk4"
    stages = 4

    def step(self, q, v, t, dt):
        acceleration, integrate, slope = self.system.acceleration, self.integrate, self.slope
        half = 0.5 * dt
        a1 = acceleration(q, v, t, 0)
        v2 = v + half * a1
        q2 = integrate(q, half * v)
        a2 = acceleration(q2, v2, t + half, 1)
        k2 = slope(q, q2, v2)
        v3 = v + half * a2
        q3 = integrate(q, half * k2)
        a3 = acceleration(q3, v3, t + half, 2)
        k3 = slope(q, q3, v3)
        v4 = v + dt * a3
        q4 = integrate(q, dt * k3)
        a4 = acceleration(q4, v4, t + dt, 3)
        sixth = dt / 6.0
        return integrate(q, sixth * (v + 2.0 * (k2 + k3) + slope(q, q4, v4))), v + sixth * (a1 + 2.0 * (a2 + a3) + a4)


class ExplicitRungeKutta(Integrator):
    """An explicit Runge-Kutta scheme given by its tableau (nodes c, coupling a, weights b); stage
    slopes are stacked so that each stage costs one matrix product.

    Attributes:
        nodes: c_i (s,). coupling: a_ij (s x s, strictly lower triangular). weights: b_j (s,).
    """

    nodes: np.ndarray
    coupling: np.ndarray
    weights: np.ndarray

    def __init__(self, system: ConstrainedSystem, options: NoOptions | None = None) -> None:
        super().__init__(system, options)
        self._nv = system.model.nv
        self._slopes = np.zeros((self.stages, 2 * self._nv))  # per stage: [velocity slope | acceleration]
        self._scaled: tuple[float, np.ndarray] = (0.0, self.coupling)  # (dt, dt * coupling)

    def step(self, q, v, t, dt):
        acceleration, slope = self.system.acceleration, self.slope
        nv, slopes = self._nv, self._slopes
        if self._scaled[0] != dt:
            self._scaled = (dt, dt * self.coupling)
        scaled = self._scaled[1]
        euclidean = self.integrate is np.add
        start = np.concatenate((q, v)) if euclidean else None  # (q, v) moves by one sum per stage
        slopes[0, :nv] = v
        slopes[0, nv:] = acceleration(q, v, t, 0)
        for stage in range(1, self.stages):
            increment = scaled[stage, :stage] @ slopes[:stage]
            if euclidean:
                state = start + increment
                q_stage, v_stage = state[:nv], state[nv:]
            else:
                q_stage, v_stage = self.integrate(q, increment[:nv]), v + increment[nv:]
            slopes[stage, nv:] = acceleration(q_stage, v_stage, t + self.nodes[stage] * dt, stage)
            slopes[stage, :nv] = slope(q, q_stage, v_stage)
        increment = (dt * self.weights) @ slopes
        return self.integrate(q, increment[:nv]), v + increment[nv:]


def _lower_triangle(rows: dict[int, dict[int, float]], stages: int) -> np.ndarray:
    matrix = np.zeros((stages, stages))
    for i, row in rows.items():
        for j, value in row.items():
            matrix[i, j] = value
    return matrix


class DormandPrince853(ExplicitRungeKutta):
    """Dormand-Prince 8(5,3) with fixed steps: its order-8 solution, 12 stages. For smooth motions it
    reaches a given accuracy with steps several times longer than RK4's (``benchmarks/``)."""

    name = "dop853"
    stages = 12
    nodes = np.array(tableaus.NODES)
    coupling = _lower_triangle(tableaus.COUPLING, 12)
    weights = np.array([tableaus.WEIGHTS.get(j, 0.0) for j in range(12)])


register_polynomial(
    DormandPrince853.name,
    tuple(
        [1.0]
        + [
            float(DormandPrince853.weights @ np.linalg.matrix_power(DormandPrince853.coupling, k) @ np.ones(12))
            for k in range(12)
        ]
    ),
)

INTEGRATORS: Registry[Integrator] = Registry("integrator")
"""Integrators. A factory is ``factory(system, options) -> Integrator``."""
INTEGRATORS.register("euler", Euler, summary="explicit Euler, order 1")
INTEGRATORS.register("semi-implicit-euler", SemiImplicitEuler, summary="symplectic Euler (v first), order 1")
INTEGRATORS.register("heun", Heun, summary="Heun's method, order 2")
INTEGRATORS.register("rk4", RK4, summary="classical Runge-Kutta, order 4")
INTEGRATORS.register("dop853", DormandPrince853, summary="Dormand-Prince, order 8, 12 stages, fixed step")
