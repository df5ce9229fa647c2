"""Explicit integrators on the configuration Lie group: ``euler``, ``semi-implicit-euler``, ``heun``, ``rk4``.

Positions advance with ``pin.integrate``. For the Runge-Kutta schemes every stage velocity is
carried back to the tangent space at the step's start point with ``pin.dDifference`` (exact
``dexp^-1``, Runge-Kutta-Munthe-Kaas), which is the identity on models made of 1-DOF joints.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .registry import NoOptions, Registry

if TYPE_CHECKING:
    from .system import ConstrainedSystem, Evaluation


class Step(NamedTuple):
    """A step's end state and the dynamics evaluated at its start (for multipliers)."""

    q: np.ndarray
    v: np.ndarray
    start: Evaluation


class Integrator:
    """One explicit step of ``dq/dt = v``, ``dv/dt = a(q, v, t)``.

    Args:
        system: the stepping system (its ``dynamics`` and its model's group operations).
        options: the integrator's options (none for the built-in schemes).
    """

    name = ""

    def __init__(self, system: ConstrainedSystem, options: NoOptions | None = None) -> None:
        self.system = system

    def step(self, q: np.ndarray, v: np.ndarray, t: float, dt: float) -> Step:
        """One step of ``dt`` [s] from (q, v) at time t [s]."""
        raise NotImplementedError

    def _runge_kutta(self, q, v, t, dt, nodes, weights) -> Step:
        system = self.system
        model = system.model
        first = system.dynamics(q, v, t)
        velocity_slopes, acceleration_slopes = [v], [first.acceleration]
        for stage, (row, node) in enumerate(nodes, start=1):
            dq = dt * sum(c * k for c, k in zip(row, velocity_slopes, strict=False))  # row covers the slopes so far
            v_stage = v + dt * sum(c * k for c, k in zip(row, acceleration_slopes, strict=False))
            q_stage = model.integrate(q, dq)
            evaluation = system.dynamics(q_stage, v_stage, t + node * dt, stage)
            velocity_slopes.append(model.to_start_tangent(q, q_stage, v_stage))
            acceleration_slopes.append(evaluation.acceleration)
        dq = dt * sum(w * k for w, k in zip(weights, velocity_slopes, strict=True))
        dv = dt * sum(w * k for w, k in zip(weights, acceleration_slopes, strict=True))
        return Step(model.integrate(q, dq), v + dv, first)


class Euler(Integrator):
    """Explicit Euler: q+ = q (+) dt v, v+ = v + dt a(q, v). Order 1."""

    name = "euler"

    def step(self, q, v, t, dt):
        first = self.system.dynamics(q, v, t)
        return Step(self.system.model.integrate(q, dt * v), v + dt * first.acceleration, first)


class SemiImplicitEuler(Integrator):
    """Symplectic Euler, velocity first: v+ = v + dt a(q, v), q+ = q (+) dt v+. Order 1."""

    name = "semi-implicit-euler"

    def step(self, q, v, t, dt):
        first = self.system.dynamics(q, v, t)
        v_new = v + dt * first.acceleration
        return Step(self.system.model.integrate(q, dt * v_new), v_new, first)


class Heun(Integrator):
    """Heun's two-stage Runge-Kutta method. Order 2."""

    name = "heun"

    def step(self, q, v, t, dt):
        return self._runge_kutta(q, v, t, dt, nodes=[((1.0,), 1.0)], weights=(0.5, 0.5))


class RK4(Integrator):
    """Classical four-stage Runge-Kutta. Order 4."""

    name = "rk4"
    NODES = [((0.5,), 0.5), ((0.0, 0.5), 0.5), ((0.0, 0.0, 1.0), 1.0)]
    WEIGHTS = (1 / 6, 1 / 3, 1 / 3, 1 / 6)

    def step(self, q, v, t, dt):
        return self._runge_kutta(q, v, t, dt, self.NODES, self.WEIGHTS)


INTEGRATORS: Registry[Integrator] = Registry("integrator")
"""Integrators. A factory is ``factory(system, options) -> Integrator``."""
INTEGRATORS.register("euler", Euler, summary="explicit Euler, order 1")
INTEGRATORS.register("semi-implicit-euler", SemiImplicitEuler, summary="symplectic Euler (v first), order 1")
INTEGRATORS.register("heun", Heun, summary="Heun's method, order 2")
INTEGRATORS.register("rk4", RK4, summary="classical Runge-Kutta, order 4")
