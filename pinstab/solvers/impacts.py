"""Impacts of contacts: Newton's restitution on the normal velocity, Coulomb's law on the impulses.

At an instant where contacts close, the velocities jump: ``v+ = v- + M^-1 W^T P``, P (k, 3) [N s] the
impulses of the contacts involved, each in its basis (n, t1, t2). With u = W v each contact's velocity in its
basis and e its restitution, per contact

    0 <= P_n  _|_  u_n+ + e u_n- >= 0,    |P_t| <= mu P_n,    P_t = -mu P_n u_t+ / |u_t+|  when u_t+ != 0

(De Saxce's bipotential form of Coulomb's law at the velocity level: the largest dissipation over the round
cone). It is the cone problem of :mod:`.ncp` with ``sigma = D P + g``, ``g = u- + (e u_n-, 0, 0)`` per
contact: a contact that pushes leaves at ``u_n+ = -e u_n-`` (a sliding one too: the NCP mode has no
lift-off), a sticking impact ends with ``u_t+ = 0``, a sliding one with its impulse on the cone against
``u_t+``. Redundant contacts (a box landing flat on four corners) leave P non-unique and v+ unique.

Newton's law at several contacts at once can create energy: a box landing spinning on four corners, two with
e = 1 and two with e = 0, may leave with 0.3 % more kinetic energy than it came with. The kinetic energy an impact
adds is the work of its impulses, ``sum P . (u- + u+) / 2``; when Newton's impact would add some, every contact's e
is scaled by the largest common factor s in [0, 1] at which it adds none (found by bisection; s = 0, a plastic
impact, only takes energy): an impact never creates energy, and one that creates none is Newton's exactly (a single
frictionless contact's always: it loses ``(1 - e^2) u_n-^2 / (2 D)``, D its Delassus number).

The solver's answer meets the law only to :data:`~pinstab.solvers.ncp.CHECK_RTOL` of the problem's velocity scale,
which a contact far from its body's centre (a long lever: Delassus numbers of 1e7 m/s per N s beside ones of 1e2)
may leave approaching at some 1e-8 m/s after an impact with e = 0: faster than
:data:`~pinstab.solvers.mode_choice.TOUCH_SPEED`, so that it is not touching, its gap closes again at once and
the next impact leaves it the same, for ever (0.01 kg cylinder, a contact 1 m out: 1300 impacts in 1e-8 s). The
answer is therefore polished (:func:`_polished`): on the set it identifies (the contacts that push, and those left
approaching faster than their target; sliding ones on their cone's edge, their friction turning with their normal
impulse, sticking ones' tangential impulses kept), one linear solve of the normal rows puts each normal velocity
after the impact on its target ``-e u_n-``; the polished impulses are kept when they push and meet the law at
least as well as the solver's.

A joint limit's impact is frictionless and one row: :func:`limit_impact` (equality rows, closures kept).
"""

from __future__ import annotations

import itertools
from typing import NamedTuple

import numpy as np

from .contact_modes import ModeDynamics, ModeSolution
from .ncp import CONE_ROWS, NcpSolver, ncp_residual

IMPULSE_SLACK = 1e-12  # relative: a joint limit's impulse below -this (of the largest) would pull
IMPACT_SPEED = 1e-9  # [rad/s, m/s] a joint limit left approaching slower than this after an impact is at rest
REST_SPEED = 1e-6  # [rad/s, m/s] a touching joint limit an impact leaves slower than this is held (Zeno cut)
ENERGY_SLACK = 1e-9  # [-] of the energy an impact's impulses exchange (P . D P / 2): the work it may add as rounding
# (the NCP is solved to 1e-12 m/s on the contact velocities); more is energy created, and the restitutions are scaled
ENERGY_BISECTIONS = 40  # halvings of the restitutions' common factor: to 2^-40 ~ 1e-12 of it
CONE_EDGE = 1e-7  # relative: a tangential impulse within this of mu P_n is on the cone's edge (the solver's answer
# meets the law to CHECK_RTOL = 1e-6 of the velocity scale; an interior impulse this close to the edge moves little)


class Impact(NamedTuple):
    """The velocities after an impact [m/s, rad/s] and each contact's impulse (k, 3) [N s] in its basis
    (n, t1, t2) (or each joint limit's (L,) [N m s or N s]), zero for those not involved."""

    velocity: np.ndarray
    impulses: np.ndarray


def impact(
    dynamics: ModeDynamics, solver: NcpSolver, v: np.ndarray, solution: ModeSolution, restitutions: dict[int, float]
) -> Impact:
    """The impact at velocities ``v`` of the contacts ``restitutions`` names, each with its Newton's e [-]
    (0 for a contact already touching); ``solution``: :meth:`ModeDynamics.solve` at the impact's state (its
    Jacobians, contact velocities and M^-1 W^T)."""
    newton = _scaled_impact(dynamics, solver, v, solution, restitutions, 1.0)
    if _added_energy(solution, newton) <= 0.0 or not any(restitutions.values()):
        return newton
    low, high, kept = 0.0, 1.0, None  # low: a factor whose impact adds no energy (0: a plastic impact)
    for _ in range(ENERGY_BISECTIONS):
        middle = 0.5 * (low + high)
        trial = _scaled_impact(dynamics, solver, v, solution, restitutions, middle)
        if _added_energy(solution, trial) <= 0.0:
            low, kept = middle, trial
        else:
            high = middle
    return kept if kept is not None else _scaled_impact(dynamics, solver, v, solution, restitutions, 0.0)


def _scaled_impact(
    dynamics: ModeDynamics,
    solver: NcpSolver,
    v: np.ndarray,
    solution: ModeSolution,
    restitutions: dict[int, float],
    factor: float,
) -> Impact:
    """The impact of :func:`impact` with every restitution multiplied by ``factor`` [-]."""
    active = sorted(restitutions)
    contacts = solution.contacts
    offset = contacts.velocities.ravel().copy()
    for i in active:
        offset[3 * i] += factor * restitutions[i] * contacts.velocities[i, 0]
    mus = [dynamics.contacts[i].mu for i in active]
    impulses = np.zeros((len(dynamics.contacts), 3))
    impulses[active] = solver.solve_contacts(contacts.jacobian, solution.mobility, offset, active, mus)
    impulses = _polished(solution, offset, impulses, active, mus)
    return Impact(v + solution.mobility @ impulses.ravel(), impulses)


def _polished(
    solution: ModeSolution, offset: np.ndarray, impulses: np.ndarray, active: list[int], mus: list[float]
) -> np.ndarray:
    """The impulses (k, 3) [N s] of an impact after one exact solve on the active set the solver's ``impulses``
    identify (see the module): each normal velocity after it of the contacts that push or approach faster than
    their target is put on its target (``offset``: u- with ``e u_n-`` added on the normal rows, so that the target
    is ``D P + offset = 0`` there). Returns ``impulses`` unchanged when the polished ones would pull or meet the
    law worse."""
    delassus = solution.contacts.jacobian @ solution.mobility
    after = offset + delassus @ impulses.ravel()  # each normal row: u_n+ + e u_n- (0 on target)
    friction = dict(zip(active, mus, strict=True))
    chosen = [i for i in active if impulses[i, 0] > 0.0 or after[3 * i] < 0.0]
    if not chosen:
        return impulses
    columns, slips = [], {}
    for i in chosen:
        column = delassus[:, 3 * i].copy()
        tangential, mu = impulses[i, 1:], friction[i]
        norm = float(np.hypot(*tangential))
        if mu > 0.0 and norm > 0.0 and norm >= mu * impulses[i, 0] * (1.0 - CONE_EDGE):  # sliding: on the edge
            slips[i] = mu * tangential / norm
            column += delassus[:, 3 * i + 1 : 3 * i + 3] @ slips[i]
        columns.append(column)
    normals = [3 * i for i in chosen]
    step = np.linalg.lstsq(np.column_stack(columns)[normals], -after[normals], rcond=1e-12)[0]
    polished = impulses.copy()
    for i, change in zip(chosen, step, strict=True):
        polished[i, 0] += change
        if i in slips:
            polished[i, 1:] += change * slips[i]
    if np.any(polished[chosen, 0] < 0.0):
        return impulses
    rows = np.array([3 * i + r for i in active for r in CONE_ROWS])
    block, g = delassus[np.ix_(rows, rows)], offset[rows]
    worse = ncp_residual(block, g, polished.ravel()[rows], mus) > ncp_residual(block, g, impulses.ravel()[rows], mus)
    return impulses if worse else polished


def _added_energy(solution: ModeSolution, result: Impact) -> float:
    """The kinetic energy [J] the impact ``result`` adds beyond rounding (:data:`ENERGY_SLACK`): its impulses'
    work ``sum P . (u- + u+) / 2`` [N s m/s], u the contact velocities before and after; <= 0 when it adds none."""
    before = solution.contacts.velocities.ravel()
    after = solution.contacts.jacobian @ result.velocity
    impulses = result.impulses.ravel()
    work = float(impulses @ (before + after)) / 2.0
    exchanged = abs(float(impulses @ (after - before))) / 2.0
    return work - ENERGY_SLACK * exchanged


def limit_impact(
    dynamics: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, restitutions: dict[int, float]
) -> Impact:
    """The impact at (q, v, t) of the joint limits ``restitutions`` names (those reached, held or touching), each
        with its Newton's e [-], the model's bilateral rows kept (their velocity unchanged). The limits S that take an
        impulse solve ``B dv = d``, ``M dv = B^T P`` with ``d = -(1 + e) u`` on their gap rates u and 0 on the closure
        rows; S is the largest set (the first in order, from all of them down) whose impulses push (above
        ``-IMPULSE_SLACK``, relative) and after which the others do not approach their bound (rate above
        ``-IMPACT_SPEED``): the impact's complementarity problem, solved by enumeration. A limit that S leaves
    separating slower than ``REST_SPEED`` would be brought back at once, over and over (a Zeno sequence): it is held
    too, its impulse however small. Returns the velocities after
        it and each limit's impulse (L,) [N m s or N s], zero for those outside S."""
    terms = dynamics.model.dynamics_terms(q, v, t)
    saved = list(dynamics.active)
    named = sorted(restitutions)
    try:
        for size in range(len(named), 0, -1):
            for chosen in itertools.combinations(named, size):
                result = _limit_impulses(dynamics, terms, q, v, chosen, restitutions)
                if result is None:
                    continue
                resting = [
                    i for i in named if i not in chosen and dynamics.limits[i].speed(result.velocity) < REST_SPEED
                ]
                if not resting:
                    return result
                forced = tuple(sorted((*chosen, *resting)))  # a Zeno sequence of impacts cut: held
                return _limit_impulses(dynamics, terms, q, v, forced, restitutions, signed=False)
    finally:
        dynamics.active[:] = saved
    return Impact(v, np.zeros(len(dynamics.limits)))


def _limit_impulses(dynamics: ModeDynamics, terms, q, v, chosen, restitutions, signed: bool = True) -> Impact | None:
    """The impact of the limits ``chosen`` (see :func:`limit_impact`), or None when it is not consistent (with
    ``signed``: an impulse that pulls too)."""
    dynamics.active[:] = [i in chosen for i in range(len(dynamics.limits))]
    jacobian, velocity, _ = dynamics.bilateral_rows(terms, q, v)
    closures = jacobian.shape[0] - len(chosen)
    change = np.zeros(jacobian.shape[0])
    change[closures:] = [-(1.0 + restitutions[i]) * velocity[closures + r] for r, i in enumerate(chosen)]
    mobility = np.linalg.solve(terms.mass_matrix, jacobian.T)
    impulses = np.linalg.lstsq(jacobian @ mobility, change, rcond=1e-12)[0]
    own = impulses[closures:]
    if signed and np.min(own) < -IMPULSE_SLACK * (1.0 + float(np.max(np.abs(own)))):
        return None
    after = v + mobility @ impulses
    others = [i for i in restitutions if i not in chosen]
    if any(dynamics.limits[i].speed(after) < -IMPACT_SPEED for i in others):
        return None
    limits = np.zeros(len(dynamics.limits))
    limits[list(chosen)] = own
    return Impact(after, limits)
