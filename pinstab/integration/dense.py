"""Dense output: the motion between the two ends of a step, on the configuration group.

A step from (q0, v0, a0) at t0 to (q1, v1, a1) at t1 is interpolated in the tangent space at q0: the
increment ``d(t) = q0 (-) q(t)`` is the polynomial that matches the increment, its rate and its second
derivative at both ends (quintic Hermite, error O(h^6) in q), and ``q(t) = q0 (+) d(t)``. On models
whose joints have one velocity coordinate each the rate of the increment is the velocity and its second
derivative the acceleration; on others (free flyers, spherical joints) the end velocity is carried to
q0's tangent space with ``pin.dDifference`` and the end acceleration is left out (quartic, O(h^5)),
since its transport needs the derivative of that map. The coefficients and the polynomial's value are the compiled
ones (``cpp/adaptive.cpp``), which the compiled error-controlled loop samples with.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ..kernels import hermite_coefficients, hermite_state

if TYPE_CHECKING:
    from ..model import ConstrainedModel


def _hermite_inverse(*points: tuple[float, int]) -> np.ndarray:
    """The matrix mapping the values p^(order)(point) at the given (point, order) pairs to the coefficients
    c_k of the polynomial p(u) = sum_k c_k u^k that takes them."""
    degree = len(points)
    derivatives = [
        [math.perm(k, order) * point ** (k - order) if k >= order else 0.0 for k in range(degree)]
        for point, order in points
    ]
    return np.linalg.inv(np.array(derivatives))


QUINTIC = _hermite_inverse((0.0, 0), (0.0, 1), (0.0, 2), (1.0, 0), (1.0, 1), (1.0, 2))
QUARTIC = _hermite_inverse((0.0, 0), (0.0, 1), (0.0, 2), (1.0, 0), (1.0, 1))
CUBIC = _hermite_inverse((0.0, 0), (0.0, 1), (1.0, 0), (1.0, 1))


class Segment:
    """The interpolated motion of one step, from t0 to t1 [s].

    Args:
        model: the constrained model (its group operations).
        t0, q0, v0, a0: the start: time [s], configuration, velocity, acceleration.
        t1, q1, v1, a1: the end. Without accelerations (None: a saved run's samples), cubic Hermite (O(h^4)).
    """

    def __init__(
        self,
        model: ConstrainedModel,
        t0: float,
        q0: np.ndarray,
        v0: np.ndarray,
        a0: np.ndarray | None,
        t1: float,
        q1: np.ndarray,
        v1: np.ndarray,
        a1: np.ndarray | None,
    ) -> None:
        self.model, self.t0, self.t1, self.q0 = model, float(t0), float(t1), q0.copy()
        h = self.t1 - self.t0
        self.h = h
        if model.euclidean:
            increment, rate = q1 - q0, v1
        else:
            increment, rate = model.difference(q0, q1), model.to_start_tangent(q0, q1, v1)
        if a0 is None or a1 is None:
            self.coefficients = hermite_coefficients(CUBIC, np.array([np.zeros_like(v0), h * v0, increment, h * rate]))
            return
        ends = [np.zeros_like(v0), h * v0, h * h * a0, increment, h * rate]
        inverse = QUARTIC
        if model.flat:
            ends.append(h * h * a1)
            inverse = QUINTIC
        self.coefficients = hermite_coefficients(
            inverse, np.array(ends)
        )  # (degree + 1, nv): p(u) = sum_k c_k u^k, u = (t - t0) / h

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) at time t [s] (t0 <= t <= t1)."""
        increment, rate = hermite_state(self.coefficients, (t - self.t0) / self.h if self.h else 0.0, self.h)
        model = self.model
        if model.euclidean:
            return self.q0 + increment, rate
        q = model.integrate(self.q0, increment)
        if model.flat:
            return q, rate
        # rate = dDifference(q0, q) v: back to the velocity at q
        jacobian = pin.dDifference(model.model, self.q0, q, pin.ArgumentPosition.ARG1)
        return q, np.linalg.solve(jacobian, rate)
