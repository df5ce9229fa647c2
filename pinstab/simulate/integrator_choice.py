"""``integrator="auto"`` (``pinstab run --integrator auto``): the integrator picked by the step-size criterion at the
run's start, and reported in the run's JSON (``info.integrator_choice``: ``picked``, ``reason``, ``stiff_mode``).

The default explicit scheme (``rk4``, ``dop853`` with rtol/atol) when the run's step is within :data:`MARGIN` of its
stability limit of the stiffest mode a force element owns at the start (:func:`~pinstab.stability.modes.stiffest_mode`),
or when no element owns a decaying one; else an implicit integrator of the registry (``Integrator.implicit``): one with
an error estimator under rtol/atol, else a fixed-step one, ``implicit-midpoint`` first. The margin is the stiff-mode
watch's assumption (:data:`~pinstab.integration.stiffness.MODE_GROWTH`): the limit at the start may shrink as the motion
goes on (stiff-fourbar's |lambda| grows from 7159 /s at the start to 8846 /s, a factor 1.24, within the first second).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import PinstabError
from ..integration import INTEGRATORS
from ..integration.stiffness import MODE_GROWTH, implicit_integrators, suggested_step
from ..model import ConstrainedModel
from ..scene import Scene
from ..stability.criterion import mode_step_limit
from ..stability.modes import stiffest_mode

AUTO = "auto"  # the integrator name that asks for the choice
MARGIN = 1.0 / MODE_GROWTH  # an explicit step is picked up to this share of its limit at the start


def error_controlled(name: str) -> bool:
    """Whether the registered integrator ``name`` has an error estimator (rtol/atol)."""
    return len(getattr(INTEGRATORS.entry(name).factory, "estimators", ())) > 0


def choose_integrator(
    scene: Scene, q: np.ndarray, v: np.ndarray, dt: float, explicit: str, controlled: bool
) -> tuple[str, dict[str, Any]]:
    """The integrator of an ``auto`` run of ``scene`` from (q, v) [rad or m, rad/s or m/s] with step ``dt`` [s]:
    ``explicit`` (the default explicit scheme) or an implicit one (error-controlled when ``controlled``), and the choice
    as the JSON reports it.

    Raises:
        PinstabError: the step is above the explicit scheme's margin and no implicit integrator (with an error
            estimator when ``controlled``) is registered, naming the element, the step to use and what is registered.
    """
    model = ConstrainedModel(scene)
    mode = stiffest_mode(model, q, v, 0.0) if model.forces else None
    if mode is None or mode.element is None or not mode.eigenvalue.real < 0:
        reason = "no force elements" if not model.forces else "no force element owns a decaying stiffest mode"
        return explicit, {"picked": explicit, "reason": reason, "stiff_mode": None}
    limit = mode_step_limit(mode.eigenvalue, explicit)
    stiff = {
        "element": mode.element,
        "frequency": mode.frequency,
        "eigenvalue": [mode.eigenvalue.real, mode.eigenvalue.imag],
        "step_limit": limit,
    }
    stated = (
        f"dt = {dt * 1e3:.3g} ms against {explicit}'s stability limit {limit * 1e3:.3g} ms of the stiff mode of force "
        f"element '{mode.element}' at the start (|lambda| = {abs(mode.eigenvalue):.3g} /s, {mode.frequency:.4g} "
        f"rad/s; margin {MARGIN:g})"
    )
    if dt <= MARGIN * limit:
        return explicit, {"picked": explicit, "reason": f"{stated}: within", "stiff_mode": stiff}
    implicit = implicit_integrators()
    fitting = [name for name in implicit if error_controlled(name) == controlled] or ([] if controlled else implicit)
    if not fitting:
        kind = "implicit integrator with an error estimator (rtol/atol)" if controlled else "implicit integrator"
        registered = f" (implicit ones registered: {', '.join(implicit)})" if implicit else ""
        raise PinstabError(
            f"integrator auto: {stated}: above, and no {kind} is registered{registered}; use --dt "
            f"{suggested_step(MARGIN * limit):g} or smaller with --integrator {explicit}"
        )
    return fitting[0], {"picked": fitting[0], "reason": f"{stated}: above", "stiff_mode": stiff}
