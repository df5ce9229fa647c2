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
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .contact_modes import ModeDynamics, ModeSolution
from .ncp import NcpSolver


class Impact(NamedTuple):
    """The velocities after an impact [m/s, rad/s] and each contact's impulse (k, 3) [N s] in its basis
    (n, t1, t2), zero for the contacts not involved."""

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
