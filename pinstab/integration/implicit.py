"""Diagonally implicit Runge-Kutta schemes on the configuration group: ``implicit-euler`` (order 1, L-stable),
``implicit-midpoint`` (order 2, A-stable, symplectic) and ``esdirk4`` (Kennedy and Carpenter's ESDIRK4(3)6L[2]SA:
order 4, L-stable, stiffly accurate, with an embedded order-3 solution for error control).

Each tableau is written with an explicit first stage (a_1j = 0, evaluated at the step's start: the stabilizers'
stage 0) and a non-zero diagonal below it; implicit Euler and the midpoint rule are their one-stage tableaus behind
that first stage, which gives the Newton iteration its first guess. A stage's equation is solved in the tangent
space at the step's start by a simplified Newton iteration on the reduced nv x nv matrix
I - h g dadv - (h g)^2 dadq, globalized when it does not converge (a continuation in the stage's share, Newton's
iteration with a Jacobian at every iterate; ``cpp/implicit.hpp``, where the arithmetic lives; the Jacobians are the
kernel's, by default finite differences of its evaluation, ``cpp/jacobian.cpp``). The Newton state (the Jacobian, the
factorization, the last rate of convergence) belongs to the compiled step object, which the Python step and the
compiled loop share: both take the same steps to the last bit.

A stage that Newton's iteration cannot solve, even globalized, ends a fixed-step run with
:class:`~pinstab.errors.NewtonError` (the trajectory so far kept); under error control the step is rejected and
shortened, like one whose error is above the tolerance.

Coefficients: C. A. Kennedy and M. H. Carpenter, *Additive Runge-Kutta schemes for convection-diffusion-reaction
equations*, Appl. Numer. Math. 44 (2003) 139-181, ARK4(3)6L[2]SA, its implicit (ESDIRK) part; the same digits as
SUNDIALS ARKode's ARK436L2SA_DIRK_6_3_4 (BSD-3-Clause). ``tests/test_implicit.py`` checks them by the order
conditions (to order 4, the embedded solution's to 3) and stiff accuracy.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..errors import NewtonError
from ..kernels import NewtonFailure, RungeKutta
from ..stability.regions import register_tableau
from .schemes import INTEGRATORS, TableauScheme
from .tableaus import Tableau

if TYPE_CHECKING:
    import pinocchio as pin

NEWTON_TOLERANCE = 1e-10  # fixed steps: Newton's rtol and atol [-, rad, m, rad/s, m/s], reached to kappa = 1
NEWTON_ITERATIONS = 10  # at most per stage
NEWTON_KAPPA = 0.03  # error control: the iteration stops within min(this, sqrt(rtol)) of the step's tolerance


def newton_kappa(rtol: float) -> float:
    """The share of the step's tolerances [-] at which Newton's iteration stops under error control: Hairer and
    Wanner's RADAU5 rule min(0.03, sqrt(rtol)) (on stiff-fourbar over 4 s, esdirk4 at rtol 1e-9: 3.1e-7 rad with a
    share of 0.01, 1.2e-7 with 1e-3, at 10 % more evaluations)."""
    return min(NEWTON_KAPPA, math.sqrt(rtol))


IMPLICIT_EULER = Tableau(
    nodes=(0.0, 1.0), coupling={1: {1: 1.0}}, weights={1: 1.0}, order=1, estimators=(), estimator_order=0
)
"""Implicit Euler behind an explicit first stage: y1 = y0 + h f(y1). L-stable, R(z) = 1 / (1 - z)."""

IMPLICIT_MIDPOINT = Tableau(
    nodes=(0.0, 0.5), coupling={1: {1: 0.5}}, weights={1: 1.0}, order=2, estimators=(), estimator_order=0
)
"""The implicit midpoint rule behind an explicit first stage: y1 = y0 + h f((y0 + y1) / 2) (for a linear f). A-stable,
symplectic, R(z) = (1 + z/2) / (1 - z/2): |R| = 1 on the imaginary axis (no numerical damping)."""

_GAMMA = 1 / 4
_WEIGHTS = {0: 82889 / 524892, 2: 15625 / 83664, 3: 69875 / 102672, 4: -2260 / 8211, 5: _GAMMA}

EMBEDDED_WEIGHTS = {
    0: 4586570599 / 29645900160,
    2: 178811875 / 945068544,
    3: 814220225 / 1159782912,
    4: -3700637 / 11593932,
    5: 61727 / 225920,
}
"""ESDIRK4's embedded order-3 weights b_hat (its estimator is b - b_hat)."""

ESDIRK4 = Tableau(
    nodes=(0.0, 1 / 2, 83 / 250, 31 / 50, 17 / 20, 1.0),
    coupling={
        1: {0: 1 / 4, 1: _GAMMA},
        2: {0: 8611 / 62500, 1: -1743 / 31250, 2: _GAMMA},
        3: {0: 5012029 / 34652500, 1: -654441 / 2922500, 2: 174375 / 388108, 3: _GAMMA},
        4: {
            0: 15267082809 / 155376265600,
            1: -71443401 / 120774400,
            2: 730878875 / 902184768,
            3: 2285395 / 8070912,
            4: _GAMMA,
        },
        5: _WEIGHTS,
    },
    weights=_WEIGHTS,
    order=4,
    estimators=({j: _WEIGHTS[j] - EMBEDDED_WEIGHTS[j] for j in _WEIGHTS},),
    estimator_order=3,
)
"""ESDIRK4(3)6L[2]SA (Kennedy and Carpenter 2003): 6 stages, the first explicit, diagonal 1/4; order 4, L-stable and
stiffly accurate (b = the last row of a: the step ends on its last stage, whose slope is the new point's); its
estimator b - b_hat (:data:`EMBEDDED_WEIGHTS`)."""


class ImplicitRungeKutta(TableauScheme):
    """A diagonally implicit Runge-Kutta scheme given by its tableau, stepped by ``cpp/implicit.cpp`` through
    :class:`~pinstab.kernels.RungeKutta` (whose Newton state the compiled loop shares: :meth:`compiled_tableau`)."""

    implicit = True

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        register_tableau(cls.name, cls.coupling, cls.weights)

    def compiled_tableau(self, group: pin.Model | None) -> RungeKutta:
        """The compiled step, its Newton iteration stopped at :data:`NEWTON_TOLERANCE`."""
        newton = (NEWTON_TOLERANCE, NEWTON_TOLERANCE, 1.0, NEWTON_ITERATIONS)
        return RungeKutta(self.nodes, self.coupling, self.weights, group, newton)

    @property
    def compiled(self) -> RungeKutta:
        """The compiled step (the same object for the Python step and the compiled loop: one Newton state)."""
        return self._tableau

    def attempt(self, q, v, t, dt, first=None, end=False):
        """:meth:`TableauScheme.attempt`.

        Raises:
            NewtonError: a stage that Newton's iteration did not solve, even globalized.
        """
        try:
            return super().attempt(q, v, t, dt, first, end)
        except NewtonFailure as failure:
            raise NewtonError(f"the {self.name} step: {failure}", t, q, v, diverged_at=t) from None

    def newton_figures(self) -> dict[str, int]:
        """What Newton's iteration did in the steps of this stepper's compiled step so far."""
        return newton_figures(self._tableau.newton)


def newton_figures(counts: tuple[int, int, int, int, int, int]) -> dict[str, int]:
    """The run summary's figures of a compiled step's ``newton`` counts: iterations (evaluations of the dynamics),
    Jacobians, LU factorizations, failures (stages not solved), the globalized iteration's Newton iterations (a
    Jacobian at the iterate each) and its continuation's shares s < 1 of a stage solved on the way to s = 1."""
    iterations, jacobians, factorizations, failures, globalized, continuation = counts
    return {
        "newton_iterations": iterations,
        "jacobian_evaluations": jacobians,
        "lu_factorizations": factorizations,
        "newton_failures": failures,
        "globalized_iterations": globalized,
        "continuation_shares": continuation,
    }


class ImplicitEuler(ImplicitRungeKutta):
    """Implicit Euler: y1 = y0 + h f(t1, y1). Order 1, L-stable."""

    name = "implicit-euler"
    tableau = IMPLICIT_EULER


class ImplicitMidpoint(ImplicitRungeKutta):
    """The implicit midpoint rule. Order 2, A-stable, symplectic (no numerical damping of an undamped linear
    oscillator)."""

    name = "implicit-midpoint"
    tableau = IMPLICIT_MIDPOINT


class Esdirk4(ImplicitRungeKutta):
    """ESDIRK4(3)6L[2]SA. Order 4, L-stable, stiffly accurate; with rtol its embedded order-3 solution controls the
    step (:mod:`pinstab.integration.adaptive`), the dense output from the ends' states and slopes."""

    name = "esdirk4"
    tableau = ESDIRK4


INTEGRATORS.register("implicit-euler", ImplicitEuler, summary="implicit Euler, order 1, L-stable (Newton)")
INTEGRATORS.register(
    "implicit-midpoint", ImplicitMidpoint, summary="implicit midpoint, order 2, A-stable, symplectic (Newton)"
)
INTEGRATORS.register(
    "esdirk4",
    Esdirk4,
    summary="ESDIRK4(3)6L[2]SA, order 4, L-stable (Newton); with --rtol 4(3) error control",
)
