"""Time-stepping contacts: a velocity-level Moreau-Jean scheme with impulses on the exact round cone.

One step of ``dt`` from (q, v) at t, for plane contacts (:class:`~pinstab.solvers.contact_modes.PlaneContactGeometry`):

    v_free = v + dt M^-1 (tau - h)
    v+     = v_free + M^-1 J^T lambda          (J: the contact points' Jacobians in their bases)
    q+     = q (+) dt v+                       (pin.integrate)

The impulses lambda [N s] of the contacts whose gap would close within the step (``gap + dt (J v_free)_n
<= 0``) solve the frictional contact problem of :mod:`pinstab.solvers.ncp` (Pinocchio's ADMM in NCP mode:
the exact round cone, a sliding contact keeps its normal velocity at its bound, no lift-off) with
``sigma = J v+ + b``, ``b = (b_n, 0, 0)`` per contact:

* ``b_n = gap / dt``: the gap at the step's end, ``gap + dt v_n+``, is non-negative. For an open contact it
  lets the gap close exactly within the step (no hovering above the plane); for a penetration (the chord
  ``dt v+`` misses the arc of a rotating body by O(dt^2)) it is the velocity-level Baumgarte/ERP term of
  the stabilizers (docs/mathematics.md section 3.3) with decay factor r = 0 per step: the deviation obeys
  ``gap_{k+1} = r gap_k``, dead-beat, the automatic choice of ``mukharlyamov``'s kinematic variant. It was
  chosen over a post-step projection because it needs no second solve: the correction is one more term of
  the same cone problem, so it can never push a contact out of its cone (a projection of the penetrating
  contacts alone could move the sticking ones).
* Newton's impact law: a contact approaching with normal velocity ``v_n < 0`` at the step's start and
  restitution e > 0 leaves at ``v_n+ >= -e v_n`` (``b_n = min(gap / dt, e v_n)``), Moreau's form.

Each contact's mode over the step is read from the solution: *separated* when it is not in the problem or
its normal impulse changes its normal velocity by less than :data:`SPEED_FLOOR`; *sliding* when its slip
speed at the step's end exceeds :data:`SPEED_FLOOR` (its impulse then lies on the cone's boundary, against
the slip); *sticking* otherwise (the point held, the impulse inside or on the cone). Every change is a
:class:`~pinstab.contact.modes.ContactEvent` (cause ``impulse``) at the step's end, where its velocity holds;
the first step records every contact's mode (cause ``start``) at the step's start. Every cone solve is
checked against the contact law (:meth:`~pinstab.solvers.ncp.NcpSolver.solve_contacts`: ADMM, PGS when ADMM's
answer misses) and counted in the run's solver statistics (status ``ADMM converged``, ``PGS converged``, a
fallback, or ``ADMM, PGS not converged``, the solver's iterations and its absolute primal and dual residuals
[m/s]); a step whose solve no solver met ends the run with a :class:`~pinstab.errors.ContactSolveError` (exit 5,
the run kept up to the step's start), never with a state off the law. The scheme is of order 1 (semi-implicit
Euler between events; an impact or a switch is located to within a step): a contact point on a rotating body
ends a step up to ``dt^2 omega^2 r / 2`` inside its plane (the chord ``dt v+`` against the arc, ``r`` the point's
distance from the axis), which the next step's gap term takes back.
"""

from __future__ import annotations

import math

import numpy as np

from ..contact.modes import ContactEvent, Mode, as_tuple
from ..errors import ContactSolveError
from ..solvers.contact_modes import ModeDynamics
from ..solvers.ncp import NcpSolver
from ..system import ConstrainedSystem
from .schemes import Integrator

SPEED_FLOOR = 1e-9  # [m/s] a slip, or a normal velocity change by an impulse, below this is none


class ContactStepper(Integrator):
    """The velocity-level step of the module, as an integrator for the stepping loop.

    Args:
        system: the scene's system without its contacts (free bodies, applied forces).
        dynamics: the contacts' kinematics (gaps, Jacobians in their bases).
        solver: the cone problem's solver.

    Attributes:
        events: the contact events so far. modes: each contact's mode over the last step (None before it).
        impulses: the last step's impulses (k, 3) [N s] in the contact bases (n, t1, t2).
    """

    name = "moreau-jean"

    def __init__(self, system: ConstrainedSystem, dynamics: ModeDynamics, solver: NcpSolver) -> None:
        super().__init__(system)
        self.dynamics = dynamics
        self.solver = solver
        count = len(dynamics.contacts)
        self.events: list[ContactEvent] = []
        self.modes: list[Mode] | None = None
        self.impulses = np.zeros((count, 3))
        self._index = {contact.name: i for i, contact in enumerate(dynamics.contacts)}

    def step(self, q: np.ndarray, v: np.ndarray, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """One step of ``dt`` [s] from (q, v) at t [s]; returns (q+, v+)."""
        if self.events and self.events[-1].t > t + dt / 2:
            self._rewind(t + dt / 2)
        model = self.system.model
        terms = model.dynamics_terms(q, v, t)
        contacts = self.dynamics.kinematics_from_kin(v)
        solved = np.linalg.solve(terms.mass_matrix, np.column_stack([terms.tau - terms.bias, contacts.jacobian.T]))
        v_free, mobility = v + dt * solved[:, 0], solved[:, 1:]
        reach = contacts.jacobian @ v_free
        active = tuple(int(i) for i in np.flatnonzero(contacts.gaps + dt * reach[0::3] <= 0.0))
        impulses = np.zeros_like(self.impulses)
        v_new = v_free
        if active:
            offset = reach.copy()
            for i in active:
                offset[3 * i] += self._normal_bias(i, contacts.gaps[i], contacts.velocities[i, 0], dt)
            mus = [self.dynamics.contacts[i].mu for i in active]
            impulses[np.array(active)] = self.solver.solve_contacts(contacts.jacobian, mobility, offset, active, mus)
            self.solver.record(self.system.solver.statistics)
            if not self.solver.status().converged:
                raise self._unsolved(active, t)
            v_new = v_free + mobility @ impulses.ravel()
        velocities = (contacts.jacobian @ v_new).reshape(-1, 3)
        normal = contacts.jacobian[0::3]
        self._track(t, dt, impulses, velocities, np.einsum("ij,ji->i", normal, mobility[:, 0::3]))
        self.impulses = impulses
        return self.integrate(q, dt * v_new), v_new

    def _rewind(self, t: float) -> None:
        """Forget the events after t [s] and take back the modes before them: the loop replays steps it took
        (after a failed check or solve, to locate it; its probes of a smaller step)."""
        self.events = [event for event in self.events if event.t <= t]
        modes = [Mode.SEPARATED] * len(self.impulses)  # the first step's events give every contact's mode
        for event in self.events:
            modes[self._index[event.contact]] = Mode(event.after)
        self.modes = modes

    def _unsolved(self, active: tuple[int, ...], t: float) -> ContactSolveError:
        """The error of a step from t [s] whose contact problem (the contacts ``active``) no solver met."""
        names = [self.dynamics.contacts[i].name for i in active]
        return ContactSolveError(
            f"at t = {t:.9g} s the impulses of contacts {', '.join(names)} were not found: {self.solver.failure()} "
            "m/s; the run is kept up to t; event-driven contacts (contacts='event', --contacts event) or another dt "
            "pose other problems",
            names,
            t,
        )

    def _normal_bias(self, i: int, gap: float, normal_velocity: float, dt: float) -> float:
        """b_n of contact i [m/s]: the gap's term, or Newton's impact law when it asks for more."""
        restitution = self.dynamics.contacts[i].restitution
        bias = gap / dt
        if restitution > 0.0 and normal_velocity < 0.0:
            bias = min(bias, restitution * normal_velocity)
        return bias

    def _track(self, t: float, dt: float, impulses: np.ndarray, velocities: np.ndarray, reach: np.ndarray) -> None:
        """Read each contact's mode over the step (``reach``: the normal velocity a unit normal impulse gives
        each contact [m/s / N s]) and record the changes."""
        modes = []
        for i in range(len(impulses)):
            if impulses[i, 0] * reach[i] <= SPEED_FLOOR:
                modes.append(Mode.SEPARATED)
            elif math.hypot(*velocities[i, 1:]) > SPEED_FLOOR:
                modes.append(Mode.SLIDING)
            else:
                modes.append(Mode.STICKING)
        start = self.modes is None
        before = [Mode.SEPARATED] * len(modes) if start else self.modes
        for i, (old, new) in enumerate(zip(before, modes, strict=True)):
            if start or old is not new:
                self.events.append(
                    ContactEvent(
                        t if start else t + dt,
                        self.dynamics.contacts[i].name,
                        old.value,
                        new.value,
                        "start" if start else "impulse",
                        as_tuple(impulses[i] / dt),
                        as_tuple(velocities[i, 1:]),
                        as_tuple(impulses[i]),
                    )
                )
        self.modes = modes
