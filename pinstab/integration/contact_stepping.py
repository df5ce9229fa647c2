"""Time-stepping contacts: a velocity-level Moreau-Jean scheme with impulses on the exact round cone.

One step of ``dt`` from (q, v) at t, for plane contacts (:class:`~pinstab.solvers.contact_modes.PlaneContactGeometry`):

    v_free = v + dt (M^-1 (tau - g - c(w)) - turn(w))     w = (v + v_free) / 2
    v+     = v_free + M^-1 J^T lambda          (J: the contact points' Jacobians in their bases)
    q+     = q (+) dt v+                       (free flyers: moved by dt pdot+, :mod:`.free_flyers`)

M, tau and the gravity g at (q, t). Free-flyer joints are stepped in their parent's axes (:mod:`.free_flyers`:
``turn(w)`` takes their frame's turn ``-omega x v_lin`` out of their translation rows, the position moves by
``dt pdot``), and the velocity terms c(w) = C(q, w) w (h = C v + g) are taken at the free step's midpoint velocity
w (the implicit midpoint rule in them, by fixed point: :meth:`ContactStepper.free_velocity`). Both keep a free
body's kinetic energy: in the parent's axes a free flyer's translation has no velocity term left, and the midpoint
keeps ``omega^T I omega / 2`` under the gyroscopic term ``omega x I omega`` (``w^T c(w) = 0``: it does no work),
where the explicit term scaled the velocity by ``sqrt(1 + (omega dt)^2)`` each step. Explicit in the joint frame,
a frictionless ball spinning at 30 rad/s and sliding at 2 m/s gained 28 J in 3 s (from 4.78 J).

The impulses lambda [N s] of the contacts whose gap would close within the step, or stay within
:data:`~pinstab.solvers.mode_choice.TOUCH_GAP` of closed (``gap + dt (J v_free)_n <= TOUCH_GAP``: a box resting
on a box falls with it, their gap closing only once the lower one is stopped), solve the frictional contact
problem of :mod:`pinstab.solvers.ncp` (Pinocchio's ADMM in NCP mode: the exact round cone, a sliding contact keeps
its normal velocity at its bound, no lift-off) with ``sigma = J v+ + b``, ``b = (b_n, 0, 0)`` per contact:

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
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.linalg import cho_factor, cho_solve

from ..contact.modes import ContactEvent, Mode, as_tuple
from ..errors import ContactSolveError
from ..solvers.contact_modes import ModeDynamics, PlaneContactGeometry, plane_geometries
from ..solvers.mode_choice import TOUCH_GAP
from ..solvers.ncp import NcpSolver
from ..system import ConstrainedSystem
from .free_flyers import FreeFlyers
from .schemes import Integrator
from .stepping import Failure

SPEED_FLOOR = 1e-9  # [m/s] a slip, or a normal velocity change by an impulse, below this is none
# The midpoint velocity terms by fixed point: each pass shrinks the error by about |omega| dt / 2 (omega the fastest
# turn, in rad/s), 0.015 for 30 rad/s at dt = 1 ms; passes stop when v_free changes by less than MIDPOINT_TOLERANCE
# of its size (rounding of the terms is ~1e-16 of it). Fifty passes reach it while |omega| dt < 1 (half of 1e-13 at
# 0.5^45); a step turning a body by more than a radian misses it: a failed step, which the stepping loop reports as
# a divergence and, when a smaller step goes on, as dt too large for the motion (StepTooLargeError).
MIDPOINT_TOLERANCE = 1e-13
MIDPOINT_PASSES = 50


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
        self.free_flyers = FreeFlyers(system.model.model)
        self.finders: list[Any] = []
        self._declared: list[PlaneContactGeometry] = []

    def find_contacts(self, finders: list[Any]) -> None:
        """Ask ``finders`` (:class:`~pinstab.constraints.geometry_contacts.FoundContacts`) for their contacts at
        every step's start, as the event-driven loop does at every step's end: the step's contacts are the
        dynamics' others (first), then those found there, by finder, pair and point; one found before keeps its
        mode, a new one starts separated."""
        self.finders = list(finders)
        found = {name for finder in self.finders for name in finder.order}
        self._declared = [contact for contact in self.dynamics.contacts if contact.name not in found]

    def _refind(self, q: np.ndarray) -> None:
        """Take the contacts found at q as the dynamics' (see :meth:`find_contacts`)."""
        found = plane_geometries([contact for finder in self.finders for contact in finder.contacts(q)])
        contacts = self._declared + found
        if [c.name for c in contacts] == [c.name for c in self.dynamics.contacts]:
            return
        places = self.dynamics.rearrange(contacts)
        if self.modes is not None:
            self.modes = [Mode.SEPARATED if i is None else self.modes[i] for i in places]
        self.impulses = np.array([np.zeros(3) if i is None else self.impulses[i] for i in places]).reshape(-1, 3)
        self._index = {contact.name: i for i, contact in enumerate(contacts)}
        if 3 * len(contacts) > self.solver.size:
            self.solver = NcpSolver(3 * len(contacts))

    def step(self, q: np.ndarray, v: np.ndarray, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """One step of ``dt`` [s] from (q, v) at t [s]; returns (q+, v+)."""
        if self.events and self.events[-1].t > t + dt / 2:
            self._rewind(t + dt / 2)
        if self.finders:
            self._refind(q)
        model = self.system.model
        terms = model.dynamics_terms(q, v, t)
        contacts = self.dynamics.kinematics_from_kin(v)
        factor = cho_factor(terms.mass_matrix)
        v_free, mobility = (
            self.free_velocity(q, v, dt, terms.tau - terms.bias, factor),
            cho_solve(factor, contacts.jacobian.T),
        )
        reach = contacts.jacobian @ v_free
        active = tuple(int(i) for i in np.flatnonzero(contacts.gaps + dt * reach[0::3] <= TOUCH_GAP))
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
        return self.free_flyers.integrate(self.system.model.model, q, v_new, dt)

    def free_velocity(self, q: np.ndarray, v: np.ndarray, dt: float, force: np.ndarray, factor: tuple) -> np.ndarray:
        """v_free [m/s, rad/s] of a step of ``dt`` [s] from (q, v): ``force`` = tau - h(q, v) [N, N m] with the
        velocity terms c(v) of h taken back and c(w) put in, and the free flyers' ``turn(w)`` taken out, at the
        midpoint w = (v + v_free) / 2, by fixed point (``factor``: M's Cholesky factor); non-finite when the passes
        do not settle (a step too large: :class:`~.stepping.Failure`, which the stepping loop locates and names)."""
        model, data = self.system.model.model, self.system.model.scratch
        turn = self.free_flyers.turn
        v_free = v + dt * (cho_solve(factor, force) - turn(v))
        at_start = pin.nonLinearEffects(model, data, q, v).copy()  # gravity cancels in the difference
        for _ in range(MIDPOINT_PASSES):
            middle = (v + v_free) / 2
            shift = pin.nonLinearEffects(model, data, q, middle) - at_start
            v_next = v + dt * (cho_solve(factor, force - shift) - turn(middle))
            change = float(np.max(np.abs(v_next - v_free), initial=0.0))
            v_free = v_next
            if change <= MIDPOINT_TOLERANCE * float(np.max(np.abs(v_free), initial=0.0)):
                return v_free
        raise Failure(f"the velocity terms at the step's midpoint did not settle in {MIDPOINT_PASSES} passes")

    def _rewind(self, t: float) -> None:
        """Forget the events after t [s] and take back the modes before them: the loop replays steps it took
        (after a failed check or solve, to locate it; its probes of a smaller step)."""
        self.events = [event for event in self.events if event.t <= t]
        modes = [Mode.SEPARATED] * len(self.impulses)  # the first step's events give every contact's mode
        for event in self.events:
            if event.contact in self._index:  # (contacts found from geometry come and go)
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
