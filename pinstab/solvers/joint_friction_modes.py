"""Choosing the modes of joint frictions (:mod:`pinstab.forces.joint_friction`) at an event.

A joint held at a limit has its friction free (no torque): the limit holds it, and the two rows on one joint would
leave their forces not unique; the friction's mode is chosen again where the limit lets go. A joint faster than
:data:`REST_SPEED` slips the way it moves (its friction ``-friction sign(qdot)``). The other joints at rest take the
modes of the box complementarity problem on their accelerations: a sticking one's torque lies within its bound, a
slipping one's friction is at the bound and its joint accelerates the way it slips. From every joint at rest sticking,
one mode is changed at a time (principal pivoting): the sticking joint whose torque is furthest beyond its bound slips
the way that torque does not hold it, else a joint that slips against its acceleration sticks again; the contacts'
modes are chosen at each (``choose``). The problem's matrix, the joints' inverse inertia with the bilateral rows held,
is symmetric positive semi-definite; the pivots are capped at :data:`PIVOTS` per joint at rest, past which the choice is
refused, naming the joints.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..errors import ContactInfeasibleError
from .contact_modes import ModeDynamics, ModeSolution
from .mode_choice import CONSISTENCY, TOUCH_SPEED, Choice

REST_SPEED = TOUCH_SPEED  # [rad/s or m/s] a joint this slow is at rest: it may stick
PIVOTS = 4  # mode changes per joint at rest before the choice is refused


def choose_frictions(
    dynamics: ModeDynamics, v: np.ndarray, t: float, slack: float, choose: Callable[[], Choice]
) -> Choice:
    """The joint frictions' modes at velocity ``v`` and time ``t`` [s] set in ``dynamics`` (see the module), and the
    contacts' choice in them (``choose``); a torque within ``slack`` (relative) of its bound is on it.

    Raises:
        ContactInfeasibleError: the pivots do not end (naming the joint frictions at rest).
    """
    resting = []
    held = {limit.index_v for limit, active in zip(dynamics.limits, dynamics.active, strict=True) if active}
    for i, friction in enumerate(dynamics.joint_frictions):
        speed = float(v[friction.index_v])
        at_rest = abs(speed) <= REST_SPEED and friction.index_v not in held
        resting += [i] if at_rest else []
        slip = 0.0 if at_rest or friction.index_v in held else math.copysign(1.0, speed)
        dynamics.stuck[i], dynamics.slips[i] = at_rest, slip
    for _ in range(PIVOTS * len(resting) + 1):
        choice = choose()
        pivot = _inconsistent(dynamics, choice.solution, resting, slack)
        if pivot is None:
            return choice
        i, torque = pivot
        dynamics.stuck[i] = not dynamics.stuck[i]
        dynamics.slips[i] = 0.0 if dynamics.stuck[i] else -math.copysign(1.0, torque)
    names = [dynamics.joint_frictions[i].name for i in resting]
    raise ContactInfeasibleError(
        f"at t = {t:.9g} s no stick-slip assignment of the joint frictions {', '.join(names)} was found in "
        f"{PIVOTS * len(resting) + 1} pivots",
        names,
        t,
    )


def _inconsistent(
    dynamics: ModeDynamics, solution: ModeSolution, resting: list[int], slack: float
) -> tuple[int, float] | None:
    """The joint friction at rest whose mode is to change in ``solution`` and its torque [N m or N], or None: the
    sticking one furthest beyond its bound (beyond ``slack``, relative), else the first slipping against its
    acceleration."""
    torques = dynamics.joint_friction_torques(solution)
    margins = sticking_margins(dynamics, torques, slack)
    stuck = [i for i in resting if margins[i] < 0.0]
    if stuck:
        i = min(stuck, key=lambda j: margins[j])
        return i, float(torques[i])
    reach = CONSISTENCY * (1.0 + float(np.max(np.abs(solution.free))))
    for i in resting:
        friction = dynamics.joint_frictions[i]
        if not dynamics.stuck[i] and dynamics.slips[i] * solution.acceleration[friction.index_v] < -reach:
            return i, float(torques[i])
    return None


def sticking_margins(dynamics: ModeDynamics, torques: np.ndarray, slack: float) -> np.ndarray:
    """Each sticking joint friction's margin ``friction - |torque| + slack (1 + max |torques|)`` [N m or N] (negative:
    the stick breaks), ``torques`` their torques (:meth:`ModeDynamics.joint_friction_torques`); inf for the others."""
    scale = 1.0 + float(np.max(np.abs(torques), initial=0.0))
    bounds = np.array([f.friction for f in dynamics.joint_frictions])
    margins = bounds - np.abs(torques) + slack * scale
    return np.where(dynamics.stuck, margins, np.inf)
