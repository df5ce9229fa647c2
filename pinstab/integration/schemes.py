"""Explicit integrators on the configuration Lie group: ``euler``, ``semi-implicit-euler``, ``heun``, ``rk4``,
``dopri5``, ``dop853`` (the last two with embedded error estimators, for error control).

Positions advance with ``pinocchio::integrate`` (plain addition on models whose joints all have one
coordinate). For the Runge-Kutta schemes every stage velocity is carried back to the tangent space at
the step's start point with ``pinocchio::dDifference`` (exact ``dexp^-1``, Runge-Kutta-Munthe-Kaas), which
is the identity on models made of 1-DOF joints.

The schemes' arithmetic lives in C++ only (``pinstab._compiled``): the fixed schemes in ``cpp/stepping.cpp``
(:class:`~pinstab.kernels.SchemeStep`, whose step the compiled loop of :mod:`.compiled` takes too), the stages of
a tableau in ``cpp/adaptive.cpp`` (:class:`~pinstab.kernels.RungeKutta`, the trial step of the compiled
error-controlled loop). The classes here name them (stages, nodes, the scheme's code or the tableau); a step
calls back ``system.acceleration(q, v, t, stage)`` per stage: Pinocchio's own algorithm on the native path,
pinstab's KKT solve on the general one (:mod:`pinstab.system`). An exception it raises reaches the step's
caller unchanged.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..kernels import RungeKutta, SchemeStep
from ..registry import NoOptions, Registry
from ..stability.regions import register_tableau
from . import tableaus
from .tableaus import Tableau

if TYPE_CHECKING:
    import pinocchio as pin

    from ..kernels import Kernel
    from ..system import ConstrainedSystem


class Integrator:
    """One explicit step of ``dq/dt = v``, ``dv/dt = a(q, v, t)``: the registry's extension point (a registered
    integrator defines :meth:`step`).

    Args:
        system: the stepping system (its ``acceleration`` and its model's group operations).
        options: the integrator's options (none for the built-in schemes).

    Attributes:
        stages: acceleration evaluations per step.
        nodes: the times of those evaluations as shares of the step (where a step must not put one next
            to a singular configuration: :mod:`pinstab.integration.passages`).
        implicit: whether its stages solve for themselves (Newton iterations: stable on stiff modes where an explicit
            scheme's step is limited by them).
    """

    name = ""
    stages = 1
    implicit = False
    nodes: tuple[float, ...] | np.ndarray = (0.0,)

    def __init__(self, system: ConstrainedSystem, options: NoOptions | None = None) -> None:
        self.system = system

    def step(self, q: np.ndarray, v: np.ndarray, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """One step of ``dt`` [s] from (q, v) at time t [s]; returns the end state (q, v)."""
        raise NotImplementedError

    def newton_figures(self) -> dict[str, int] | None:
        """What its Newton iteration did in its steps so far (the run summary's ``newton``), None without one."""
        return None


SCHEMES = {"euler": 0, "semi-implicit-euler": 1, "heun": 2, "rk4": 3}
"""The fixed schemes by name: their codes in ``cpp/kernels.hpp`` (``Scheme``); the compiled loop takes these."""


def _group(system: ConstrainedSystem) -> pin.Model | None:
    """The model whose configuration group a compiled step integrates on, None where q (+) dq = q + dq."""
    model = system.model
    return None if model.euclidean else model.model


class FixedScheme(Integrator):
    """A scheme of ``cpp/stepping.cpp`` (its code: :data:`SCHEMES` by name)."""

    def __init__(self, system: ConstrainedSystem, options: NoOptions | None = None) -> None:
        super().__init__(system, options)
        self._scheme = SchemeStep(SCHEMES[self.name], _group(system))

    def step(self, q, v, t, dt):
        return self._scheme.step(self.system.acceleration, q, v, t, dt)


class Euler(FixedScheme):
    """Explicit Euler: q+ = q (+) dt v, v+ = v + dt a(q, v). Order 1."""

    name = "euler"


class SemiImplicitEuler(FixedScheme):
    """Symplectic Euler, velocity first: v+ = v + dt a(q, v), q+ = q (+) dt v+. Order 1."""

    name = "semi-implicit-euler"


class Heun(FixedScheme):
    """Heun's two-stage Runge-Kutta method. Order 2."""

    name = "heun"
    stages = 2
    nodes = (0.0, 1.0)


class RK4(FixedScheme):
    """Classical four-stage Runge-Kutta. Order 4."""

    name = "rk4"
    stages = 4
    nodes = (0.0, 0.5, 0.5, 1.0)


class TableauScheme(Integrator):
    """A Runge-Kutta scheme given by its tableau (:class:`~pinstab.integration.tableaus.Tableau`), stepped by
    ``cpp/adaptive.cpp`` (:class:`~pinstab.kernels.RungeKutta`): explicit (:class:`ExplicitRungeKutta`) or
    diagonally implicit (:class:`~pinstab.integration.implicit.ImplicitRungeKutta`, ``cpp/implicit.cpp``).

    Attributes:
        tableau: the coefficients. nodes: c_i (s,). coupling: a_ij (s x s, lower triangular: strictly for an
            explicit scheme). weights: b_j (s,). estimators: the error estimators' weights (one row each, s + 1
            columns: the last for the derivative at the new point), empty without one.
    """

    tableau: Tableau
    nodes: np.ndarray
    coupling: np.ndarray
    weights: np.ndarray
    estimators: np.ndarray

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        if "tableau" not in cls.__dict__:  # an intermediate base
            return
        tableau = cls.tableau
        cls.stages = len(tableau.nodes)
        cls.nodes = np.array(tableau.nodes)
        cls.coupling = _lower_triangle(tableau.coupling, cls.stages)
        cls.weights = _row(tableau.weights, cls.stages)
        cls.estimators = np.array([_row(estimator, cls.stages + 1) for estimator in tableau.estimators])

    def __init__(self, system: ConstrainedSystem, options: NoOptions | None = None) -> None:
        super().__init__(system, options)
        self._tableau = self.compiled_tableau(_group(system))

    def compiled_tableau(self, group: pin.Model | None) -> RungeKutta:
        """The compiled step of the tableau on the group of ``group`` (None: every joint of one coordinate)."""
        return RungeKutta(self.nodes, self.coupling, self.weights, group)

    def jacobian_kernel(self) -> Kernel | None:
        """The compiled kernel whose Jacobians an implicit stage's Newton iteration takes in this stepper's own steps
        (the run's compiled loop lends its own to an implicit stepper: :meth:`CompiledLoop.lend_jacobians
        <pinstab.integration.compiled.CompiledLoop.lend_jacobians>`), or None: differences of the acceleration (and
        none needed by an explicit tableau)."""
        return None

    def step(self, q, v, t, dt):
        return self.attempt(q, v, t, dt)[:2]

    def attempt(
        self, q: np.ndarray, v: np.ndarray, t: float, dt: float, first: np.ndarray | None = None, end: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """One step of ``dt`` [s] from (q, v) at t [s]; returns the end state, the stage slopes (stages x 2 nv:
        the velocity slopes in the start's tangent space, then the accelerations), which the error estimators
        weigh, and with ``end`` the new point's slope ([velocity slope | acceleration], its acceleration evaluated
        as stage 0; else None). ``first``: the acceleration at (q, v, t) when already known."""
        return self._tableau.attempt(self.system.acceleration, q, v, t, dt, first, end, self.jacobian_kernel())


class ExplicitRungeKutta(TableauScheme):
    """An explicit Runge-Kutta scheme given by its tableau (a_ij strictly lower triangular); its tableau registered
    for the step-size criterion (:func:`~pinstab.stability.regions.register_tableau`)."""

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        register_tableau(cls.name, cls.coupling, cls.weights)


def _lower_triangle(rows: dict[int, dict[int, float]], stages: int) -> np.ndarray:
    matrix = np.zeros((stages, stages))
    for i, row in rows.items():
        for j, value in row.items():
            matrix[i, j] = value
    return matrix


def _row(entries: dict[int, float], size: int) -> np.ndarray:
    return np.array([entries.get(j, 0.0) for j in range(size)])


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
        and issubclass(entry.factory, TableauScheme)
        and len(entry.factory.estimators)
    ]
