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
from .contact_modes import SLIP_FLOOR, ContactKinematics, Friction, ModeDynamics, ModeSolution, spin_name
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
    """The modes chosen, the slip directions of the sliding frictions (by index in ``dynamics.frictions``), the
    solution in them and the spins' modes."""

    modes: list[Mode]
    directions: dict[int, np.ndarray]
    solution: ModeSolution
    spin_modes: list[Mode]


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
    ``stopped`` (slow slips, frictions by index in ``dynamics.frictions``) may stick whatever their speed, as at rest:
    a slip at its end can keep a speed across its
    old direction of about SLIP_SPEED where the direction turns as it stops (allegro-tilt's ring finger: 1.0 to
    1.1e-9 m/s, which decelerating at 10 m/s^2 stops within 1e-10 s); sliding on against that speed, no mode was.

    Raises:
        PainleveError: no consistent assignment, or consistent ones with different accelerations.
    """
    kinematics = dynamics.kinematics(q, v)
    active = touching(kinematics)
    consistent = _enumerated(dynamics, q, v, t, kinematics, slack, ())
    slow = [f for f in stopped if dynamics.frictions[f].contact in active]
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
    the others; the spins of those not separated sticking or sliding when at rest (or ``stopped``), else sliding."""
    count = len(dynamics.contacts)
    active = touching(kinematics)
    options = []
    for i in active:
        options.append(_friction_options(dynamics, i, kinematics, stopped) + (Mode.SEPARATED,))
    spin_options = [_friction_options(dynamics, count + j, kinematics, stopped) for j in range(len(dynamics.spins))]
    if len(active) > ENUMERATED:
        options = [choices[:1] for choices in options]  # the first assignment, then the NCP's (see the module)
        spin_options = [choices[:1] for choices in spin_options]
    consistent: list[Choice] = []
    for assignment in itertools.product(*options):
        modes = [Mode.SEPARATED] * count
        for i, mode in zip(active, assignment, strict=True):
            modes[i] = mode
        live = [j for j, spin in enumerate(dynamics.spins) if modes[spin.contact] is not Mode.SEPARATED]
        for spin_assignment in itertools.product(*(spin_options[j] for j in live)):
            spin_modes = [Mode.STICKING] * len(dynamics.spins)
            for j, mode in zip(live, spin_assignment, strict=True):
                spin_modes[j] = mode
            choice = _consistent(dynamics, q, v, t, modes, spin_modes, active, kinematics, slack, stopped)
            if choice is not None:
                consistent.append(choice)
    return consistent


def _friction_options(
    dynamics: ModeDynamics, f: int, kinematics: ContactKinematics, stopped: Collection[int]
) -> tuple[Mode, ...]:
    """The modes friction f may take: sliding when it slips (and is not ``stopped``), else sticking or sliding."""
    slipping = f not in stopped and math.hypot(*kinematics.rates()[dynamics.frictions[f].rows]) > SLIP_SPEED
    return (Mode.SLIDING,) if slipping else (Mode.STICKING, Mode.SLIDING)


def _differences(dynamics: ModeDynamics, first: Choice, other: Choice) -> list[tuple[str, Mode, Mode]]:
    names = [c.name for c in dynamics.contacts]
    names += [spin_name(names[s.contact], s) for s in dynamics.spins]
    return [
        (name, a, b)
        for name, a, b in zip(names, first.modes + first.spin_modes, other.modes + other.spin_modes, strict=True)
        if a is not b
    ]


def _consistent(
    dynamics: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    modes: list[Mode],
    spin_modes: list[Mode],
    active: list[int],
    kinematics,
    slack: float,
    stopped: Collection[int] = (),
) -> Choice | None:
    """The choice of ``modes`` and ``spin_modes`` when consistent at (q, v, t), else None (the frictions ``stopped``
    slide from rest)."""
    directions = {}
    rates = kinematics.rates()
    for f, friction in enumerate(dynamics.frictions):
        if friction.contact in active and dynamics.sliding(f, modes, spin_modes):
            slip = rates[friction.rows]
            speed = math.hypot(*slip)
            directions[f] = slip / speed if speed > SLIP_SPEED and f not in stopped else None
    starting = [f for f, d in directions.items() if d is None]
    solution = _solve_with_directions(dynamics, q, v, t, (modes, spin_modes), directions, starting)
    if solution is None:
        return None
    found = {f: d for f, d in directions.items() if d is not None}
    return _checked(dynamics, solution, (modes, spin_modes), active, slack, found, [])


def _checked(
    dynamics: ModeDynamics,
    solution: ModeSolution,
    assignment: tuple[list[Mode], list[Mode]],
    active: list[int],
    slack: float,
    directions: dict[int, np.ndarray],
    starting: list[int],
) -> Choice | None:
    """The choice of ``assignment`` (the contacts' modes, the spins') if ``solution`` is consistent: touching contacts
    push, separated ones do not approach, sticking forces and torques can lie in their bounds and the frictions in
    ``starting`` (sliding from rest) slip along their ``directions``; else None."""
    modes, spin_modes = assignment
    forces, contacts = solution.forces, solution.contacts
    scale = 1.0 + float(np.max(np.abs(solution.loads()), initial=0.0))
    accelerations = contacts.jacobian @ solution.acceleration + contacts.drift
    acceleration_scale = 1.0 + float(np.max(np.abs(contacts.jacobian @ solution.free), initial=0.0))
    for i in active:
        mode = modes[i]
        if mode is Mode.SEPARATED:
            if accelerations[3 * i] < -CONSISTENCY * acceleration_scale:
                return None
        elif forces[i, 0] < -slack * scale:
            return None
    rates = solution.slip_rates()
    for f in starting:
        if rates[dynamics.frictions[f].rows] @ directions[f] < -CONSISTENCY * acceleration_scale:
            return None
    if any(modes[i] is Mode.STICKING for i in active) and sticking_margin(dynamics, solution, modes) < -slack * scale:
        return None
    if spin_margin(dynamics, solution, modes, spin_modes) < -slack * scale:
        return None
    return Choice(modes, directions, solution, spin_modes)


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
    spin_modes = [_friction_options(dynamics, count + j, kinematics, stopped)[0] for j in range(len(dynamics.spins))]
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
        solution = dynamics.solve(q, v, t, modes, spin_modes)
    finally:
        dynamics.directions[:] = saved
    return _checked(dynamics, solution, (modes, spin_modes), active, slack, directions, list(directions))


def _solve_with_directions(
    dynamics: ModeDynamics,
    q: np.ndarray,
    v: np.ndarray,
    t: float,
    assignment: tuple[list[Mode], list[Mode]],
    directions: dict[int, np.ndarray | None],
    starting: list[int],
) -> ModeSolution | None:
    """Solve ``assignment`` (the contacts' modes, the spins'); the frictions in ``starting`` slide from rest in the
    direction of their own slip acceleration (a fixed point, from the direction opposite the force or torque that
    sticking would need; where that acceleration vanishes, at the bound, the direction stays). None when the
    direction does not settle (the slip acceleration turns against the friction: it would not slip)."""
    modes, spin_modes = assignment
    saved = list(dynamics.directions)
    try:
        if starting:
            held, held_spins = list(modes), list(spin_modes)
            for f in starting:
                friction = dynamics.frictions[f]
                if friction.spin is None:
                    held[f] = Mode.STICKING
                else:
                    held_spins[friction.spin] = Mode.STICKING
            loads = dynamics.solve(q, v, t, held, held_spins).loads()
            for f in starting:
                force = loads[dynamics.frictions[f].rows]
                norm = math.hypot(*force)
                dynamics.directions[f] = -force / norm if norm > 0 else np.eye(force.size)[0]
        for f, d in directions.items():
            if d is not None:
                dynamics.directions[f] = d
        for _ in range(DIRECTION_ITERATIONS):
            solution = dynamics.solve(q, v, t, modes, spin_modes)
            if not starting:
                return solution
            rates = solution.slip_rates()
            changed = 0.0
            for i in starting:
                slip = rates[dynamics.frictions[i].rows]
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
        return np.array([m for i in sticking for m in (f[3 * i], cone_margin(f, dynamics.frictions[i]))])

    direct = float(margins(forces.ravel()).min())
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


def cone_margin(loads: np.ndarray, friction: Friction) -> float:
    """How far a friction's forces (or torques) in ``loads`` (:meth:`ModeSolution.loads`) lie inside its bound:
    ``bound f_n - |f|`` [N, or N m for a spin]."""
    return friction.bound * loads[friction.normal] - math.hypot(*loads[friction.rows])


def torque_margin(loads: np.ndarray, friction: Friction) -> float:
    """A spin's :func:`cone_margin` per unit bound, ``f_n - |tau| / bound`` [N]: comparable with the forces' slack."""
    return cone_margin(loads, friction) / friction.bound


def spin_margin(dynamics: ModeDynamics, solution: ModeSolution, modes: list[Mode], spin_modes: list[Mode]) -> float:
    """The smallest margin of the sticking spins in ``solution`` (contacts in ``modes``, spins in ``spin_modes``),
    per unit bound: ``f_n - |tau| / bound`` [N] (inf when none sticks). Their torques are the smallest that give the
    motion (redundant spins share theirs evenly, not at their best)."""
    loads = solution.loads()
    margins = [
        torque_margin(loads, friction)
        for friction in dynamics.frictions[len(dynamics.contacts) :]
        if modes[friction.contact] is not Mode.SEPARATED and spin_modes[friction.spin] is Mode.STICKING
    ]
    return min(margins, default=math.inf)
