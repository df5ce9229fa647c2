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

from typing import NamedTuple

import numpy as np

from .contact_modes import ModeDynamics, ModeSolution
from .ncp import NcpSolver


IMPULSE_SLACK = 1e-12  # relative: a joint limit's impulse below -this (of the largest) would pull


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


def limit_impact(dynamics: ModeDynamics, q: np.ndarray, v: np.ndarray, t: float, restitutions: dict[int, float]) -> Impact:
    """The impact at (q, v, t) of the joint limits ``restitutions`` names, each with its Newton's e [-] (0 for an
    active one), the model's bilateral rows kept (their velocity unchanged): ``B dv = d``, ``M dv = B^T P`` with
    ``d = -(1 + e) u`` on the limits' gap rates u and 0 on the closure rows. A limit whose impulse would pull
    (below ``-IMPULSE_SLACK``, relative) is left out and the impact solved again. Returns the velocities after it
    and each limit's impulse (L,) [N m s or N s], zero for the limits left out."""
    terms = dynamics.model.dynamics_terms(q, v, t)
    saved = list(dynamics.active)
    involved = sorted(restitutions)
    try:
        while True:
            dynamics.active[:] = [i in involved for i in range(len(dynamics.limits))]
            jacobian, velocity, _ = dynamics.bilateral_rows(terms, q, v)
            closures = jacobian.shape[0] - len(involved)
            change = np.zeros(jacobian.shape[0])
            change[closures:] = [-(1.0 + restitutions[i]) * velocity[closures + r] for r, i in enumerate(involved)]
            mobility = np.linalg.solve(terms.mass_matrix, jacobian.T)
            impulses = np.linalg.lstsq(jacobian @ mobility, change, rcond=1e-12)[0]
            own = impulses[closures:]
            worst = int(np.argmin(own)) if own.size else 0
            if not own.size or own[worst] >= -IMPULSE_SLACK * (1.0 + float(np.max(np.abs(own)))):
                break
            involved.pop(worst)
    finally:
        dynamics.active[:] = saved
    limits = np.zeros(len(dynamics.limits))
    limits[involved] = own
    return Impact(v + mobility @ impulses, limits)
