"""Dense output: the motion between the two ends of a step, on the configuration group.

A step from (q0, v0, a0) at t0 to (q1, v1, a1) at t1 is interpolated in the tangent space at q0: the
increment ``d(t) = q0 (-) q(t)`` is the polynomial that matches the increment, its rate and its second
derivative at both ends (quintic Hermite, error O(h^6) in q), and ``q(t) = q0 (+) d(t)``. On models
whose joints have one velocity coordinate each the rate of the increment is the velocity and its second
derivative the acceleration; on others (free flyers, spherical joints) the end velocity is carried to
q0's tangent space with ``pin.dDifference`` and the end acceleration is left out (quartic, O(h^5)),
since its transport needs the derivative of that map. The segment is the compiled one (``cpp/adaptive.cpp``), which
the compiled error-controlled loop samples with.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..kernels import Segment as CompiledSegment

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
HERMITE = (QUINTIC, QUARTIC, CUBIC)  # as the compiled segment takes them


class Segment:
    """The interpolated motion of one step, from t0 to t1 [s].

    Args:
        model: the constrained model (its group operations).
        t0, q0, v0, a0: the start: time [s], configuration, velocity, acceleration.
        t1, q1, v1, a1: the end. Without accelerations (None: a saved run's samples), cubic Hermite (O(h^4)).

    Attributes:
        t0, t1, h: the start, the end and the step [s]. q0: the start configuration. coefficients: (degree + 1, nv),
            the increment's polynomial p(u) = sum_k c_k u^k, u = (t - t0) / h.
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
        group = None if model.euclidean else model.model
        self._segment = CompiledSegment(group, HERMITE, float(t0), q0, v0, a0, float(t1), q1, v1, a1)
        self.t0, self.t1, self.h = float(t0), float(t1), self._segment.h
        self.q0, self.coefficients = self._segment.q0, self._segment.coefficients

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) at time t [s] (t0 <= t <= t1)."""
        return self._segment.state(t)
