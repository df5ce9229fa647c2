"""Time-stepping contacts: a velocity-level Moreau-Jean scheme with impulses on the exact round cone.

One step of ``dt`` from (q, v) at t, for plane contacts (:class:`~pinstab.solvers.contact_modes.PlaneContactGeometry`):

    v_free = v + dt (M^-1 (tau - g - c(w)) - turn(w))     w = (v + v+) / 2
    v+     = v_free + M^-1 J^T lambda          (J: the contact points' Jacobians in their bases)
    q+     = q (+) dt v+                       (free flyers: moved by dt pdot+)

M, tau and the gravity g at (q, t). Free-flyer joints are stepped in their parent's axes, as MuJoCo's free joints
(``pdot = R v_lin`` instead of Pinocchio's joint-frame ``v_lin``: in the joint frame a body gliding at a constant
``pdot`` has ``d v_lin / dt = -omega x v_lin``, and a step that takes this term at one velocity moves the body
along a screw, not along the velocity its impulses were computed for): ``turn(w)`` takes their frame's turn
``-omega x v_lin`` out of their translation rows, the position moves by ``p+ = p + dt R v_lin+`` and the velocity
stored is ``R+^T R v_lin+`` (the same ``pdot`` in the end's joint frame, ``R+ = R exp(dt omega+)``), and the
velocity terms c(w) = C(q, w) w (h = C v + g) are taken at the step's midpoint velocity w (the implicit midpoint
rule in them, by fixed point, :data:`MIDPOINT_PASSES` at most), the impulses' velocity change included: the first
midpoint takes it from the last step's impulses of the same contacts, and the problem is solved again from the
midpoint of its answer until the free velocity moves by at most :data:`IMPULSE_TOLERANCE` of the step's velocities.
Taken at the free step's midpoint (v + v_free) / 2, a finger pressed still onto a wall by its joint torques had its
velocity terms at the speed the torques would give it unopposed: the wall's force 6.4 % off the statics at dt = 2 ms
(12 N, a two-link finger; tests/test_stepping_midpoint.py). Both keep a free body's kinetic energy: in
the parent's axes a free flyer's translation has no velocity term left, and the midpoint keeps ``omega^T I omega /
2`` under the gyroscopic term ``omega x I omega`` (``w^T c(w) = 0``: it does no work), where the explicit term
scaled the velocity by ``sqrt(1 + (omega dt)^2)`` each step. Explicit in the joint frame, a frictionless ball
spinning at 30 rad/s and sliding at 2 m/s gained 28 J in 3 s (from 4.78 J).

The impulses lambda [N s] of the contacts whose gap would close within the step, or stay within
:data:`~pinstab.solvers.mode_choice.TOUCH_GAP` of closed (``gap + dt (J v_free)_n <= TOUCH_GAP``: a box resting
on a box falls with it, their gap closing only once the lower one is stopped), and then of those the others'
impulses close (``gap + dt (J v+)_n <= TOUCH_GAP``, solved again with them until none is added: a box held up by
half its weight on a box that the ground stops went 7.4e-6 m into it, and its 8 corners chattered between sticking
and separated, 276 events in 0.1 s, tests/test_contact_stepping.py; a grown problem whose answer no solver
finds is given up for the one before it), solve the frictional contact
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

Torsion (soft-finger friction, issue 36): a contact with a torsion length c > 0 [m] has a fourth row, the relative
angular velocity about its normal (:class:`~pinstab.solvers.contact_modes.ModeDynamics`' spin rows, the event-driven
contacts' rule), and a torque impulse there with the event modes' law: ``|lambda_tau| <= c lambda_n`` beside the
round cone over the same normal impulse, each friction at its bound against its slip when it slips (maximal
dissipation of each; De Saxce's velocity ``sigma_n + mu |sigma_t| + c |sigma_tau|``), sticking inside it. Pinocchio's
solvers have no such set; the step solves it by the ADMM of cpp/torsion_cone.hpp (Pinocchio's NCP-mode iteration on
the exact projection), checked by the same natural map, without a PGS fallback. A torsion's mode is *separated* with
its contact, else *sliding* while its spin at the step's end exceeds :data:`SPEED_FLOOR` [rad/s], else *sticking*; its
changes are events of ``<contact> torsion`` (force: normal force [N], torque [N m]). Rolling resistance is not taken.

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

The step's numbers are compiled (``pinstab._compiled.ConeStepper``, cpp/cone_step.hpp): the free velocity and its
midpoint passes (M's Cholesky factor, Pinocchio's ``nonLinearEffects``), the contacts in the problem and their biases,
the Delassus matrix, the checked cone solve (the one :meth:`~pinstab.solvers.ncp.NcpSolver.solve_contacts` calls),
the impulses' velocity change and the position update. Python keeps what the compiled step reads and what it tells:
the contacts (found by coal; gaps and Jacobians from :class:`~pinstab.solvers.contact_modes.ModeDynamics`, the rule
the event-driven contacts use), the applied forces, the modes and events, the statistics and errors.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..contact.modes import ContactEvent, Mode, as_tuple
from ..errors import ContactSolveError
from ..kernels import ConeStepper
from ..model import DynamicsTerms
from ..solvers import ncp
from ..solvers.contact_modes import ContactKinematics, ModeDynamics, PlaneContactGeometry, plane_geometries, spin_name
from ..solvers.mode_choice import TOUCH_GAP
from ..solvers.ncp import NcpSolver
from ..system import ConstrainedSystem
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
# The midpoint over the impulses: a step solves its contact problem again, the velocity terms taken at the midpoint
# of v and the answer's v+, until the free velocity that v+ gives moves by at most this much of the step's velocities
# (relative) against the one the answer was solved from; each such pass shrinks the error by about |omega| dt / 2.
IMPULSE_TOLERANCE = 1e-12


class ContactStepper(Integrator):
    """The velocity-level step of the module, as an integrator for the stepping loop.

    Args:
        system: the scene's system without its contacts (free bodies, applied forces).
        dynamics: the contacts' kinematics (gaps, Jacobians in their bases).
        solver: the cone problem's solver.

    Attributes:
        events: the contact events so far. modes: each contact's mode over the last step (None before it).
        impulses: the last step's impulses (k, 3) [N s] in the contact bases (n, t1, t2). spin_modes: each torsion's
        (the dynamics' spins) mode over the last step. torques: the last step's torque impulses [N m s] about the
        normals, one per torsion.
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
        self.spin_modes: list[Mode] = []
        self.torques = np.zeros(len(dynamics.spins))
        self._labels = self._names()
        self._index = {name: i for i, name in enumerate(self._labels)}
        self.compiled = ConeStepper(system.model.model, system.model.scratch)
        self.finders: list[Any] = []
        self._declared: list[PlaneContactGeometry] = []
        self._laws = self._contact_laws()

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
        found = [contact for finder in self.finders for contact in finder.contacts(q)]
        names = [contact.name for contact in self._declared + found]
        if names == self._labels[: len(self.impulses)]:
            return  # the same contacts (their geometries, which cost more than the search, are not rebuilt)
        contacts = self._declared + plane_geometries(found)
        spins = {name: j for j, name in enumerate(self._labels[len(self.impulses) :])}
        places = self.dynamics.rearrange(contacts)
        self._labels = self._names()
        turns = [spins.get(name) for name in self._labels[len(contacts) :]]
        if self.modes is not None:
            self.modes = [Mode.SEPARATED if i is None else self.modes[i] for i in places]
            self.spin_modes = [Mode.SEPARATED if j is None else self.spin_modes[j] for j in turns]
        self.impulses = np.array([np.zeros(3) if i is None else self.impulses[i] for i in places]).reshape(-1, 3)
        self.torques = np.array([0.0 if j is None else self.torques[j] for j in turns])
        self._index = {name: i for i, name in enumerate(self._labels)}
        self._laws = self._contact_laws()
        if 3 * len(contacts) > self.solver.size:
            self.solver = NcpSolver(3 * len(contacts))

    def step(self, q: np.ndarray, v: np.ndarray, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """One step of ``dt`` [s] from (q, v) at t [s]; returns (q+, v+).

        Raises:
            Failure: the velocity terms at the step's midpoint did not settle in :data:`MIDPOINT_PASSES` passes (a
                step too large: the stepping loop locates and names it).
            ContactSolveError: no solver met the contact law of the step's contacts.
        """
        terms, contacts = self.start(q, v, t, dt)
        mus, restitutions, torsions = self._laws
        settings = np.array([TOUCH_GAP, MIDPOINT_TOLERANCE, MIDPOINT_PASSES, ncp.CHECK_RTOL, IMPULSE_TOLERANCE])
        guess = np.concatenate([self.impulses.reshape(-1), self.torques])
        q_next, v_next, active, impulses, velocities, reach, torques, spins, settled, solved = self.compiled.step(
            q,
            v,
            dt,
            terms.mass_matrix,
            terms.tau - terms.bias,
            contacts.gaps,
            np.ascontiguousarray(contacts.velocities[:, 0]),
            contacts.jacobian,
            mus,
            restitutions,
            torsions,
            contacts.spin_jacobian.reshape(-1, self.system.model.nv),
            guess,
            settings,
            self.solver.cones,
        )
        if not settled:
            raise Failure(f"the velocity terms at the step's midpoint did not settle in {MIDPOINT_PASSES} passes")
        if active:
            self.solver.read_status()
            self.solver.record(self.system.solver.statistics)
            if not solved:
                raise self._unsolved(tuple(active), t)
        self._track(t, dt, impulses, velocities, reach, torques, spins)
        return q_next, v_next

    def start(self, q: np.ndarray, v: np.ndarray, t: float, dt: float) -> tuple[DynamicsTerms, ContactKinematics]:
        """What a step of ``dt`` [s] from (q, v) at t [s] reads, M, h and the applied forces and the contacts' gaps
        and Jacobians, after taking back the events of a step the loop replays and finding the contacts at q."""
        if self.events and self.events[-1].t > t + dt / 2:
            self._rewind(t + dt / 2)
        if self.finders:
            self._refind(q)
        return self.system.model.dynamics_terms(q, v, t), self.dynamics.kinematics_from_kin(v)

    def _rewind(self, t: float) -> None:
        """Forget the events after t [s] and take back the modes before them: the loop replays steps it took
        (after a failed check or solve, to locate it; its probes of a smaller step)."""
        self.events = [event for event in self.events if event.t <= t]
        modes = [Mode.SEPARATED] * len(self._index)  # the first step's events give every contact's and torsion's mode
        for event in self.events:
            if event.contact in self._index:  # (contacts found from geometry come and go)
                modes[self._index[event.contact]] = Mode(event.after)
        self.modes, self.spin_modes = modes[: len(self.impulses)], modes[len(self.impulses) :]

    def _contact_laws(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The contacts' friction coefficients mu [-], restitutions e [-] and torsion lengths c [m], in their order
        (each contiguous: the compiled step reads them without a strided copy)."""
        laws = [(contact.mu, contact.restitution, contact.torsion) for contact in self.dynamics.contacts]
        mus, restitutions, torsions = np.array(laws, dtype=float).reshape(-1, 3).T.copy()
        return mus, restitutions, torsions

    def _names(self) -> list[str]:
        """The names of the contacts' modes and events: the contacts', then their torsions' (``ground torsion``)."""
        contacts = self.dynamics.contacts
        return [c.name for c in contacts] + [spin_name(contacts[s.contact].name, s) for s in self.dynamics.spins]

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

    def _track(
        self,
        t: float,
        dt: float,
        impulses: np.ndarray,
        velocities: np.ndarray,
        reach: np.ndarray,
        torques: np.ndarray,
        spins: np.ndarray,
    ) -> None:
        """Read each contact's and torsion's mode over the step (``reach``: the normal velocity a unit normal impulse
        gives each contact [m/s / N s]; ``torques`` [N m s] and ``spins`` [rad/s]: the torsions') and record the
        changes (a torsion's force and impulse: normal, torque, 0; its slip: spin, 0)."""
        apart = (impulses[:, 0] * reach <= SPEED_FLOOR).tolist()
        modes = [
            Mode.SEPARATED if away else Mode.SLIDING if math.hypot(*slip) > SPEED_FLOOR else Mode.STICKING
            for away, slip in zip(apart, velocities[:, 1:].tolist(), strict=True)
        ]
        contacts = [spin.contact for spin in self.dynamics.spins]
        spin_modes = [
            Mode.SEPARATED if modes[i] is Mode.SEPARATED else Mode.SLIDING if abs(w) > SPEED_FLOOR else Mode.STICKING
            for i, w in zip(contacts, spins, strict=True)
        ]
        start = self.modes is None
        now = modes + spin_modes
        before = [Mode.SEPARATED] * len(now) if start else self.modes + self.spin_modes
        k = len(modes)
        changed = (
            range(len(now)) if start else [j for j, (a, b) in enumerate(zip(before, now, strict=True)) if a is not b]
        )
        for j in changed:
            old, new = before[j], now[j]
            if j < k:
                load, slip = impulses[j], velocities[j, 1:]
            else:
                load = np.array([impulses[contacts[j - k], 0], torques[j - k], 0.0])
                slip = np.array([spins[j - k], 0.0])
            self.events.append(
                ContactEvent(
                    t if start else t + dt,
                    self._labels[j],
                    old.value,
                    new.value,
                    "start" if start else "impulse",
                    as_tuple(load / dt),
                    as_tuple(slip),
                    as_tuple(load),
                )
            )
        self.modes, self.spin_modes = modes, spin_modes
        self.impulses, self.torques = impulses, torques
