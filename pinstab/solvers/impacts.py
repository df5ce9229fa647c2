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

A joint limit's impact is frictionless and one row: :func:`limit_impact` (equality rows, closures kept).
"""

from __future__ import annotations

import itertools
from typing import NamedTuple

import numpy as np

from .contact_modes import ModeDynamics, ModeSolution
from .ncp import NcpSolver

IMPULSE_SLACK = 1e-12  # relative: a joint limit's impulse below -this (of the largest) would pull
IMPACT_SPEED = 1e-9  # [rad/s, m/s] a joint limit left approaching slower than this after an impact is at rest
REST_SPEED = 1e-6  # [rad/s, m/s] a touching joint limit an impact leaves slower than this is held (Zeno cut)


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
    active = sorted(restitutions)
    contacts = solution.contacts
    offset = contacts.velocities.ravel().copy()
    for i in active:
        offset[3 * i] += restitutions[i] * contacts.velocities[i, 0]
    mus = [dynamics.contacts[i].mu for i in active]
    impulses = np.zeros((len(dynamics.contacts), 3))
    impulses[active] = solver.solve_contacts(contacts.jacobian, solution.mobility, offset, active, mus)
    return Impact(v + solution.mobility @ impulses.ravel(), impulses)


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
