"""The stiff-mode watch of the stepping loop (issue 37): an explicit fixed step above its scheme's stability limit of a
force element's stiff mode stops the run (:class:`~pinstab.errors.StiffStepError`) instead of ending it with a
plausible wrong answer, and the words that name the mode and what to use instead.

At the loop's checks (every :data:`~pinstab.integration.stepping.CHECK_STEPS` steps) the motion is linearized at the
checked state (:func:`~pinstab.stability.modes.stiffest_mode`, the elements differentiated together) and the stiffest
mode's growth per step |R| is read from its eigenvalue (:func:`~pinstab.stability.criterion.mode_growth`). Measured
on ``stiff-fourbar`` with RK4 (``tests/test_stiff_watch.py``): at 0.32 ms the mode crosses its limit briefly
(|R| = 1.047 and 1.063 at two checks, a 99- and a 433-fold growth over 100 steps) and the run stays bounded, its energy
within 3.4e-3 J of a 0.02 ms run's as everywhere before; at 0.33 ms one check sits on the limit (|R| = 0.9994) and the
energy reaches 835 J within the next 100 steps; at 0.35 ms the first check over the limit has |R| = 1.104 (a 2e4-fold
growth) with the state still clean. Hence the rule: the growth over consecutive checks over the limit, each counting
|R|^CHECK_STEPS for the chunk that follows it, stops the run once above :data:`GROWTH_LIMIT`; a check within the
limit ends a crossing. The run's records end with the chunk's start and the check's state.

A linearization costs about 4 nv evaluations of the elements and of RNEA: the watch skips checks while the mode is far
from its limit. Its |lambda| changes by at most 7 % between checks over stiff-fourbar's bounded runs; assuming at most
:data:`MODE_GROWTH` per check, the next linearization comes at the last check at which the mode, grown that much, is
still within the limit (at most :data:`MAX_WAIT` checks on).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..stability.criterion import mode_growth, mode_step_limit, schemes
from ..stability.modes import StiffMode, stiffest_mode
from .schemes import INTEGRATORS

if TYPE_CHECKING:
    from ..model import ConstrainedModel
    from ..system import ConstrainedSystem
    from .schemes import Integrator

GROWTH_LIMIT = 1e3  # growth of the stiff mode over a crossing (|R|^steps) that stops the run
MODE_GROWTH = 1.25  # the largest factor the stiff mode's |lambda| is assumed to grow by between two checks
MAX_WAIT = 10  # checks at most between two linearizations
PREFERRED_IMPLICIT = ("implicit-midpoint",)  # suggested first among the registered implicit integrators


def implicit_integrators() -> list[str]:
    """The registered integrators whose stages solve for themselves (``Integrator.implicit``), preferred first."""
    names = [entry.name for entry in INTEGRATORS.entries() if getattr(entry.factory, "implicit", False)]
    return sorted(names, key=lambda name: (name not in PREFERRED_IMPLICIT, names.index(name)))


def watched(stepper: Integrator, model: ConstrainedModel) -> bool:
    """Whether a fixed-step run of ``stepper`` on ``model`` is one a stiff element's mode can limit: an explicit scheme
    whose stability function the criterion knows, on a scene with force elements."""
    return not stepper.implicit and stepper.name in schemes() and bool(model.forces)


def suggested_step(limit: float) -> float:
    """``limit`` [s] rounded down to three significant digits [s]."""
    scale = 10.0 ** (2 - math.floor(math.log10(limit)))
    return math.floor(limit * scale) / scale


def stiff_reason(scheme: str, dt: float, mode: StiffMode, limit: float, t: float) -> str:
    """Why ``dt`` [s] is too large for ``scheme``: above its stability ``limit`` [s] of ``mode``, owned by a force
    element, at t [s]; what to use instead (a step, and the registered implicit integrators)."""
    implicit = implicit_integrators()
    others = f" (or {', '.join(implicit[1:])})" if len(implicit) > 1 else ""
    instead = f", or an implicit integrator: --integrator {implicit[0]}{others}" if implicit else ""
    return (
        f"dt = {dt * 1e3:.3g} ms is above {scheme}'s stability limit {limit * 1e3:.3g} ms of the stiff mode of "
        f"force element '{mode.element}' (|lambda| = {abs(mode.eigenvalue):.3g} /s, {mode.frequency:.4g} rad/s, "
        f"at t = {t:.6g} s): use --dt {suggested_step(limit):g} or smaller (the limit changes with the state: leave a "
        f"margin){instead}"
    )


class StiffWatch:
    """The stiff-mode watch of one fixed-step run (module docstring).

    Args:
        model: the run's model. scheme: its integrator's name. dt: its step [s]. steps: steps between checks.
    """

    def __init__(self, model: ConstrainedModel, scheme: str, dt: float, steps: int) -> None:
        self.model = model
        self.scheme = scheme
        self.dt = dt
        self.steps = steps
        self.growth = 0.0  # log of the mode's growth over the current crossing
        self.wait = 0  # checks to let pass before the next linearization

    @classmethod
    def of(cls, system: ConstrainedSystem, stepper: Integrator, dt: float, steps: int) -> StiffWatch | None:
        """The watch of a run, or None where no stiff element's mode limits it (:func:`watched`)."""
        return cls(system.model, stepper.name, dt, steps) if watched(stepper, system.model) else None

    def radius(self, mode: StiffMode, scale: float = 1.0) -> float:
        """|R| per step of the mode [-] at the run's step times ``scale`` (the mode's |lambda| grown by it)."""
        return mode_growth(mode.eigenvalue, self.dt * scale, self.scheme)

    def see(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[StiffMode, float, float, float] | None:
        """At the check of (q, v, t) [rad or m, rad/s or m/s, s]: None, or when the crossing's growth is above
        :data:`GROWTH_LIMIT`, the mode (owner named), its step limit [s], its |R| per step there and the growth [-]."""
        if self.wait:
            self.wait -= 1
            return None
        mode = stiffest_mode(self.model, q, v, t, owner=False)
        if mode is None or not mode.eigenvalue.real < 0:
            self.growth = 0.0
            return None
        radius = self.radius(mode)
        if radius <= 1.0:
            self.growth = 0.0
            checks = 1
            while checks < MAX_WAIT and self.radius(mode, MODE_GROWTH ** (checks + 1)) <= 1.0:
                checks += 1
            self.wait = checks - 1
            return None
        self.growth += self.steps * math.log(radius)
        if self.growth <= math.log(GROWTH_LIMIT):
            return None
        owned = stiffest_mode(self.model, q, v, t)
        if owned is None or owned.element is None:
            return None  # no element's mode: the explicit step is not what a stiff element limits
        return owned, mode_step_limit(owned.eigenvalue, self.scheme), radius, math.exp(min(self.growth, 700.0))
