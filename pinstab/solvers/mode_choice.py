"""Choosing contact modes at an event.

At an event the contacts that touch (gap and normal velocity at zero) take the modes that solve the
contact complementarity problem on accelerations: every assignment of modes to them (sticking, sliding,
separated; a contact that slips cannot stick) is solved (:class:`~pinstab.solvers.contact_modes.ModeDynamics`)
and kept when consistent: a sticking contact's forces can lie inside its round cone and push, a sliding
contact pushes and (starting from rest) slips the way its friction opposes, a separated contact's gap does
not accelerate inwards. With few contacts the enumeration is exact and tells what a solver's iterate
cannot: no consistent assignment, or consistent ones with different motions, is Painlevé's paradox
(:class:`~pinstab.errors.PainleveError`). Among consistent assignments with the same motion (redundant
contacts) the first in the order sticking, sliding, separated is taken. When no assignment is consistent
while every touching contact is at rest along its surface (several contacts starting to slide together,
their slip directions coupled), the modes are read from the same problem solved by Pinocchio's ADMM in NCP
mode (exact round cones, friction opposing the slip acceleration) and checked the same way.

The enumeration solves 3^k assignments of k touching contacts at rest; beyond :data:`ENUMERATED` of them (a stack of
three boxes touches on twelve corners: 531,441 solves at every event) only the first assignment is tried in place of
each enumeration (each contact in its first mode: sticking, or sliding when it slips), then the modes read from the
NCP solution; the first consistent one is taken. Consistency is checked as for an enumerated one, uniqueness (the
second half of Painlevé's paradox) is not.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Collection
from typing import NamedTuple

import numpy as np

from ..contact.modes import Mode
from ..errors import PainleveError
from .contact_modes import SLIP_FLOOR, ContactKinematics, ModeDynamics, ModeSolution
from .ncp import NcpSolver

CONSISTENCY = 1e-9  # relative: forces and accelerations within this of their bounds are on them
EVENT_SLACK = 1e-12  # relative: at an event located on a force bound, forces within this of it are on it
DIRECTION_ITERATIONS = 50  # fixed-point iterations for the direction a slip starts in
TOUCH_GAP = 1e-9  # [m] a contact this close touches
TOUCH_SPEED = 1e-9  # [m/s] ... and moving apart or closing slower than this is at rest on the surface
SLIP_SPEED = SLIP_FLOOR  # [m/s] a contact point slower than this along the surface does not slip
NCP_EDGE = 1e-7  # relative: ADMM's forces within this of a cone's edge (or of zero) are on it
ENUMERATED = 6  # touching contacts whose assignments are all enumerated (3^6 = 729 solves); see the module


class Choice(NamedTuple):
    """The modes chosen, the slip directions of contacts that start sliding, and the solution in them."""

    modes: list[Mode]
    directions: dict[int, np.ndarray]
    solution: ModeSolution


def touching(kinematics: ContactKinematics) -> list[int]:
    """The contacts that touch in ``kinematics``: gap within :data:`TOUCH_GAP`, normal speed within
    :data:`TOUCH_SPEED`."""
    return [
        i
        for i, (gap, velocity) in enumerate(zip(kinematics.gaps, kinematics.velocities, strict=True))
        if gap <= TOUCH_GAP and abs(velocity[0]) <= TOUCH_SPEED
    ]


def choose_modes(
    dynamics: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    slack: float = CONSISTENCY,
    stopped: Collection[int] = (),
) -> Choice:
    """The modes of the contacts at (q, v, t): those not touching are separated, the touching ones take the
    consistent assignment (see the module); a force within ``slack`` (relative) of its bound is on it
    (:data:`EVENT_SLACK` at an event located on that bound). When no assignment is consistent, the contacts
    ``stopped`` (slow slips) may stick whatever their speed, as at rest: a slip at its end can keep a speed across its
    old direction of about SLIP_SPEED where the direction turns as it stops (allegro-tilt's ring finger: 1.0 to
    1.1e-9 m/s, which decelerating at 10 m/s^2 stops within 1e-10 s); sliding on against that speed, no mode was.

    Raises:
        PainleveError: no consistent assignment, or consistent ones with different accelerations.
    """
    kinematics = dynamics.kinematics(q, v)
    active = touching(kinematics)
    consistent = _enumerated(dynamics, q, v, t, kinematics, slack, ())
    slow = [i for i in stopped if i in active]
    if not consistent and slow:  # the slow slips stop
        consistent = _enumerated(dynamics, q, v, t, kinematics, slack, slow)
    names = [dynamics.contacts[i].name for i in active]
    if not consistent:  # e.g. several contacts starting to slide at once: their directions are coupled
        choice = _ncp_choice(dynamics, q, v, t, active, kinematics, slack, slow)
        consistent += [] if choice is None else [choice]
    if not consistent:
        tried = "" if len(active) <= ENUMERATED else f" of those tried ({len(active)} contacts touch, not enumerated)"
        raise PainleveError(
            f"at t = {t:.9g} s no contact mode{tried} of {', '.join(names)} is consistent (Painleve's paradox: the "
            "friction would need a normal force that pulls); use the time-stepping contacts, which resolve it "
            "by a tangential impulse",
            names,
            t,
        )
    first = consistent[0]
    scale = 1.0 + float(np.max(np.abs(first.solution.free)))
    for other in consistent[1:]:
        if np.max(np.abs(other.solution.acceleration - first.solution.acceleration)) > CONSISTENCY * scale * 1e3:
            described = ", ".join(f"{n}: {a.value} or {b.value}" for n, a, b in _differences(dynamics, first, other))
            raise PainleveError(
                f"at t = {t:.9g} s the contact modes are not unique ({described}): two consistent motions "
                "(Painleve's paradox); use the time-stepping contacts, which resolve it by a tangential impulse",
                names,
                t,
            )
    return first


def _enumerated(
    dynamics: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, kinematics, slack: float, stopped: Collection[int]
) -> list[Choice]:
    """Every consistent assignment of modes to the touching contacts at (q, v, t) (``kinematics`` there): sticking,
    sliding or separated for those at rest along their surface (and the ``stopped`` ones), sliding or separated for
    the others."""
    count = len(dynamics.contacts)
    active = touching(kinematics)
    options = []
    for i in active:
        slipping = i not in stopped and math.hypot(*kinematics.velocities[i, 1:]) > SLIP_SPEED
        options.append((Mode.SLIDING, Mode.SEPARATED) if slipping else (Mode.STICKING, Mode.SLIDING, Mode.SEPARATED))
    if len(active) > ENUMERATED:
        options = [choices[:1] for choices in options]  # the first assignment, then the NCP's (see the module)
    consistent: list[Choice] = []
    for assignment in itertools.product(*options):
        modes = [Mode.SEPARATED] * count
        for i, mode in zip(active, assignment, strict=True):
            modes[i] = mode
        choice = _consistent(dynamics, q, v, t, modes, active, kinematics, slack, stopped)
        if choice is not None:
            consistent.append(choice)
    return consistent


def _differences(dynamics: ModeDynamics, first: Choice, other: Choice) -> list[tuple[str, Mode, Mode]]:
    return [
        (contact.name, a, b)
        for contact, a, b in zip(dynamics.contacts, first.modes, other.modes, strict=True)
        if a is not b
    ]


def _consistent(
    dynamics: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    modes: list[Mode],
    active: list[int],
    kinematics,
    slack: float,
    stopped: Collection[int] = (),
) -> Choice | None:
    """The choice of ``modes`` when consistent at (q, v, t), else None (the contacts ``stopped`` slide from rest)."""
    directions = {}
    for i in active:
        if modes[i] is Mode.SLIDING:
            slip = kinematics.velocities[i, 1:]
            speed = math.hypot(*slip)
            directions[i] = slip / speed if speed > SLIP_SPEED and i not in stopped else None
    starting = [i for i, d in directions.items() if d is None]
    solution = _solve_with_directions(dynamics, q, v, t, modes, directions, starting)
    if solution is None:
        return None
    found = {i: d for i, d in directions.items() if d is not None}
    return _checked(dynamics, solution, modes, active, slack, found, [])


def _checked(
    dynamics: ModeDynamics,
    solution: ModeSolution,
    modes: list[Mode],
    active: list[int],
    slack: float,
    directions: dict[int, np.ndarray],
    starting: list[int],
) -> Choice | None:
    """The choice of ``modes`` if ``solution`` is consistent: touching contacts push, separated ones do not
    approach, sticking forces can lie in their cones and the contacts in ``starting`` (sliding from rest)
    slip along their ``directions``; else None."""
    forces, contacts = solution.forces, solution.contacts
    scale = 1.0 + float(np.max(np.abs(forces), initial=0.0))
    accelerations = contacts.jacobian @ solution.acceleration + contacts.drift
    acceleration_scale = 1.0 + float(np.max(np.abs(contacts.jacobian @ solution.free), initial=0.0))
    for i in active:
        mode = modes[i]
        if mode is Mode.SEPARATED:
            if accelerations[3 * i] < -CONSISTENCY * acceleration_scale:
                return None
        elif forces[i, 0] < -slack * scale:
            return None
    for i in starting:
        if accelerations[3 * i + 1 : 3 * i + 3] @ directions[i] < -CONSISTENCY * acceleration_scale:
            return None
    if any(modes[i] is Mode.STICKING for i in active) and sticking_margin(dynamics, solution, modes) < -slack * scale:
        return None
    return Choice(modes, directions, solution)


def _ncp_choice(
    dynamics: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    active: list[int],
    kinematics,
    slack: float,
    stopped: Collection[int] = (),
) -> Choice | None:
    """The modes of the touching contacts, all at rest along the surface, read from the contact problem on
    accelerations solved by Pinocchio's ADMM in NCP mode (exact round cones, friction opposing the slip
    acceleration), then checked as an enumerated assignment is; None when some contact already slips or the
    modes read are not consistent (the contacts ``stopped`` count as at rest)."""
    if not active or any(i not in stopped and math.hypot(*kinematics.velocities[i, 1:]) > SLIP_SPEED for i in active):
        return None
    count = len(dynamics.contacts)
    free = dynamics.solve(q, v, t, [Mode.SEPARATED] * count)
    contacts = free.contacts
    offset = contacts.jacobian @ free.free + contacts.drift  # the contact accelerations without forces
    mus = [dynamics.contacts[i].mu for i in active]
    forces = np.zeros((count, 3))
    forces[active] = NcpSolver(3 * len(active)).solve_contacts(contacts.jacobian, free.mobility, offset, active, mus)
    accelerations = (offset + contacts.jacobian @ (free.mobility @ forces.ravel())).reshape(-1, 3)
    scale = 1.0 + float(np.max(np.abs(forces)))
    modes, directions = [Mode.SEPARATED] * count, {}
    for i in active:
        normal, tangential = forces[i, 0], forces[i, 1:]
        if normal <= NCP_EDGE * scale:
            continue
        if math.hypot(*tangential) < dynamics.contacts[i].mu * normal - NCP_EDGE * scale:
            modes[i] = Mode.STICKING
            continue
        modes[i] = Mode.SLIDING
        slip = accelerations[i, 1:]
        along = slip if math.hypot(*slip) > CONSISTENCY * scale else -tangential
        directions[i] = along / math.hypot(*along)
    saved = list(dynamics.directions)
    try:
        for i, direction in directions.items():
            dynamics.directions[i] = direction
        solution = dynamics.solve(q, v, t, modes)
    finally:
        dynamics.directions[:] = saved
    return _checked(dynamics, solution, modes, active, slack, directions, list(directions))


def _solve_with_directions(
    dynamics: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    modes: list[Mode],
    directions: dict[int, np.ndarray | None],
    starting: list[int],
) -> ModeSolution | None:
    """Solve ``modes``; the contacts in ``starting`` slide from rest in the direction of their own tangential
    acceleration (a fixed point, from the direction opposite the force that sticking would need; where that
    acceleration vanishes, at the cone's edge, the direction stays). None when the direction does not settle
    (the tangential acceleration turns against the friction: the contact would not slip)."""
    saved = list(dynamics.directions)
    try:
        if starting:
            stuck = dynamics.solve(q, v, t, [Mode.STICKING if i in starting else m for i, m in enumerate(modes)])
            for i in starting:
                force = stuck.forces[i, 1:]
                norm = math.hypot(*force)
                dynamics.directions[i] = -force / norm if norm > 0 else np.array([1.0, 0.0])
        for i, d in directions.items():
            if d is not None:
                dynamics.directions[i] = d
        for _ in range(DIRECTION_ITERATIONS):
            solution = dynamics.solve(q, v, t, modes)
            if not starting:
                return solution
            tangential = solution.contacts.jacobian @ solution.acceleration + solution.contacts.drift
            changed = 0.0
            for i in starting:
                slip = tangential[3 * i + 1 : 3 * i + 3]
                speed = math.hypot(*slip)
                if speed <= CONSISTENCY * (1.0 + float(np.max(np.abs(solution.free)))):
                    continue  # at the cone's edge the slip starts from zero acceleration: keep its direction
                new = slip / speed
                if new @ dynamics.directions[i] < 0.0:  # the slip turns against its friction: it would not slip
                    return None
                changed = max(changed, float(np.max(np.abs(new - dynamics.directions[i]))))
                dynamics.directions[i] = new
            if changed < 1e-13:
                for i in starting:
                    directions[i] = dynamics.directions[i].copy()
                return solution
        return None
    finally:
        dynamics.directions[:] = saved


def sticking_margin(dynamics: ModeDynamics, solution: ModeSolution, modes: list[Mode]) -> float:
    """The largest, over the forces that give the same accelerations, of the smallest margin of the sticking
    contacts: their normal force and ``mu f_n - |f_t|`` [N]. Unique forces: the margin of those; redundant
    sticking rows (non-unique forces): a small second-order cone program (SciPy's SLSQP)."""
    sticking = [i for i, mode in enumerate(modes) if mode is Mode.STICKING]
    if not sticking:
        return math.inf
    forces = solution.forces

    def margins(f: np.ndarray) -> np.ndarray:
        f = f.reshape(-1, 3)
        return np.array(
            [m for i in sticking for m in (f[i, 0], dynamics.contacts[i].mu * f[i, 0] - math.hypot(f[i, 1], f[i, 2]))]
        )

    direct = float(margins(forces).min())
    rows = [r for i in sticking for r in range(3 * i, 3 * i + 3)]
    block = solution.contacts.jacobian[rows] @ solution.mobility[:, rows]
    singular_values, basis = np.linalg.svd(block)[1:]
    redundant = basis[singular_values.size - int(np.sum(singular_values <= 1e-10 * singular_values[0])) :]
    if direct >= 0.0 or redundant.shape[0] == 0:
        return direct
    from scipy.optimize import minimize

    null = np.zeros((forces.size, redundant.shape[0]))
    null[rows] = redundant.T
    start = forces.ravel()
    scale = 1.0 + float(np.max(np.abs(start)))

    def constraint(x: np.ndarray) -> np.ndarray:
        return margins(start + null @ x[:-1]) / scale - x[-1]

    result = minimize(
        lambda x: -x[-1],
        np.append(np.zeros(null.shape[1]), direct / scale),
        method="SLSQP",
        constraints=[{"type": "ineq", "fun": constraint}],
        options={"ftol": 1e-14, "maxiter": 200},
    )
    best = float(margins(start + null @ result.x[:-1]).min())
    return max(best, direct)
