"""Explicit integrators on the configuration Lie group: ``euler``, ``semi-implicit-euler``, ``heun``, ``rk4``,
``dopri5``, ``dop853`` (the last two with embedded error estimators, for error control).

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
from .tableaus import Tableau

if TYPE_CHECKING:
    from ..system import ConstrainedSystem


class Integrator:
    """One explicit step of ``dq/dt = v``, ``dv/dt = a(q, v, t)``.

    Args:
        system: the stepping system (its ``acceleration`` and its model's group operations).
        options: the integrator's options (none for the built-in schemes).

    Attributes:
        stages: acceleration evaluations per step.
        nodes: the times of those evaluations as shares of the step (where a step must not put one next
            to a singular configuration: :mod:`pinstab.integration.passages`).
    """

    name = ""
    stages = 1
    nodes: tuple[float, ...] | np.ndarray = (0.0,)

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
    nodes = (0.0, 1.0)

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
    nodes = (0.0, 0.5, 0.5, 1.0)

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
    """An explicit Runge-Kutta scheme given by its :class:`~pinstab.integration.tableaus.Tableau`; stage
    slopes are stacked so that each stage costs one matrix product.

    Attributes:
        tableau: the coefficients. nodes: c_i (s,). coupling: a_ij (s x s, strictly lower triangular).
        weights: b_j (s,). estimators: the error estimators' weights (one row each, s + 1 columns: the last
            for the derivative at the new point), empty without one.
    """

    tableau: Tableau
    nodes: np.ndarray
    coupling: np.ndarray
    weights: np.ndarray
    estimators: np.ndarray

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        tableau = cls.tableau
        cls.stages = len(tableau.nodes)
        cls.nodes = np.array(tableau.nodes)
        cls.coupling = _lower_triangle(tableau.coupling, cls.stages)
        cls.weights = _row(tableau.weights, cls.stages)
        cls.estimators = np.array([_row(estimator, cls.stages + 1) for estimator in tableau.estimators])
        register_polynomial(cls.name, stability_polynomial(cls.coupling, cls.weights))

    def __init__(self, system: ConstrainedSystem, options: NoOptions | None = None) -> None:
        super().__init__(system, options)
        self._nv = system.model.nv
        self._slopes = np.zeros((self.stages, 2 * self._nv))  # per stage: [velocity slope | acceleration]
        self._scaled: tuple[float, np.ndarray] = (0.0, self.coupling)  # (dt, dt * coupling)

    def step(self, q, v, t, dt):
        q_new, v_new, _ = self.attempt(q, v, t, dt)
        return q_new, v_new

    def attempt(
        self, q: np.ndarray, v: np.ndarray, t: float, dt: float, first: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One step of ``dt`` [s] from (q, v) at t [s]; returns the end state and the stage slopes
        (stages x 2 nv: the velocity slopes in the start's tangent space, then the accelerations), which
        the error estimators weigh. ``first``: the acceleration at (q, v, t) when already known."""
        acceleration, slope = self.system.acceleration, self.slope
        nv, slopes = self._nv, self._slopes
        if self._scaled[0] != dt:
            self._scaled = (dt, dt * self.coupling)
        scaled = self._scaled[1]
        euclidean = self.integrate is np.add
        start = np.concatenate((q, v)) if euclidean else None  # (q, v) moves by one sum per stage
        slopes[0, :nv] = v
        slopes[0, nv:] = acceleration(q, v, t, 0) if first is None else first
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
        return self.integrate(q, increment[:nv]), v + increment[nv:], slopes


def _lower_triangle(rows: dict[int, dict[int, float]], stages: int) -> np.ndarray:
    matrix = np.zeros((stages, stages))
    for i, row in rows.items():
        for j, value in row.items():
            matrix[i, j] = value
    return matrix


def _row(entries: dict[int, float], size: int) -> np.ndarray:
    return np.array([entries.get(j, 0.0) for j in range(size)])


def stability_polynomial(coupling: np.ndarray, weights: np.ndarray) -> tuple[float, ...]:
    """The coefficients of a tableau's stability polynomial, lowest degree first: 1, then b^T a^(k-1) 1."""
    ones = np.ones(len(weights))
    return tuple([1.0] + [float(weights @ np.linalg.matrix_power(coupling, k) @ ones) for k in range(len(weights))])


class DormandPrince853(ExplicitRungeKutta):
    """Dormand-Prince 8(5,3): its order-8 solution, 12 stages. For smooth motions it reaches a given
    accuracy with steps several times longer than RK4's (``benchmarks/``); with ``rtol`` its embedded
    estimators control the step (:mod:`pinstab.integration.adaptive`)."""

    name = "dop853"
    tableau = tableaus.DOP853


class DormandPrince5(ExplicitRungeKutta):
    """Dormand-Prince 5(4): its order-5 solution, 6 stages (the error estimator adds the new point's
    derivative, the next step's first stage)."""

    name = "dopri5"
    tableau = tableaus.DOPRI5


INTEGRATORS: Registry[Integrator] = Registry("integrator")
"""Integrators. A factory is ``factory(system, options) -> Integrator``."""
INTEGRATORS.register("euler", Euler, summary="explicit Euler, order 1")
INTEGRATORS.register("semi-implicit-euler", SemiImplicitEuler, summary="symplectic Euler (v first), order 1")
INTEGRATORS.register("heun", Heun, summary="Heun's method, order 2")
INTEGRATORS.register("rk4", RK4, summary="classical Runge-Kutta, order 4")
INTEGRATORS.register(
    "dopri5", DormandPrince5, summary="Dormand-Prince, order 5, 6 stages; with --rtol 5(4) error control"
)
INTEGRATORS.register(
    "dop853", DormandPrince853, summary="Dormand-Prince, order 8, 12 stages; with --rtol 8(5,3) error control"
)


def embedded_pairs() -> list[str]:
    """The registered integrators with an error estimator (usable with rtol/atol)."""
    return [
        entry.name
        for entry in INTEGRATORS.entries()
        if isinstance(entry.factory, type)
        and issubclass(entry.factory, ExplicitRungeKutta)
        and len(entry.factory.estimators)
    ]
