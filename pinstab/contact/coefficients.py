"""Friction and restitution coefficients as a scene table or a generator parameter gives them: plain numbers in
their physical ranges, refused by name otherwise (:class:`~pinstab.errors.SceneError`).
"""

from __future__ import annotations

from ..errors import SceneError

MAX_FRICTION = 10.0  # [-] the largest Coulomb friction coefficient mu
FRICTION_REASON = (
    "measured friction coefficients of dry solids are below about 2 (rubber, clean metals; beyond, as for metals "
    "outgassed in vacuum, the surfaces cold-weld and Coulomb's law does not hold), and a cone of mu = 10 already "
    "holds every force but those within 5.7 deg of the surface; larger values only take the contact solvers out "
    "of their range (event-driven contacts report a false Painleve paradox for a cube at rest from mu = 8e5, and "
    "from 1e15 a sliding rod falls through the floor)"
)
RESTITUTION_REASON = "Newton's e: 0 plastic, 1 elastic; beyond 1 an impact creates energy"


def friction_coefficient(value: object, where: str) -> float:
    """A Coulomb friction coefficient mu [-] in [0, :data:`MAX_FRICTION`].

    Raises:
        SceneError: naming ``where`` (e.g. ``contact 'end'.mu``), the value and the allowed range.
    """
    return _coefficient(value, where, MAX_FRICTION, FRICTION_REASON)


def restitution_coefficient(value: object, where: str) -> float:
    """Newton's coefficient of restitution e [-] in [0, 1].

    Raises:
        SceneError: naming ``where``, the value and the allowed range.
    """
    return _coefficient(value, where, 1.0, RESTITUTION_REASON)


def _coefficient(value: object, where: str, high: float, reason: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 <= value <= high:
        raise SceneError(f"{where} must be a number in [0, {high:g}] [-], got {value!r}: {reason}")
    return float(value)
