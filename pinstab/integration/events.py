"""Event-driven contacts: the error-controlled loop (:mod:`.adaptive`) with contact modes that switch.

Between events the contacts keep their modes (:class:`~pinstab.solvers.contact_modes.ModeDynamics`). After
every accepted step each contact's event function is evaluated: a separated contact's gap (from where it was
released when that was a rounding below its plane: else a contact released there moving off, as slowly as
nanometres per second, closes again at once, over and over: 145 s of wall time for 0.12 s), a sticking
contact's smallest force margin (normal force; ``mu f_n - |f_t|``, the best over the forces when they are
not unique), a sliding contact's normal force and its slip velocity along the direction it had at the
step's start; forces count as below their bound only beyond the relative
:data:`~pinstab.solvers.mode_choice.EVENT_SLACK` the mode choice then allows, so that a contact on its bound
does not switch back and forth. Within a step a sliding mode is continued past its end (its friction keeps the
slip's direction at the step's start once the slip turns against it), so that the step is smooth across the end.
When an event function turns negative, its root is located by bisection on the step's dense output, then found again
on the pair's steps from the step's start to :data:`EVENT_TIME` [s] (a joint limit's dip: on the dense output), the
step is taken again to end there, and at that instant a gap that closed with an approaching velocity (within
:data:`~pinstab.solvers.mode_choice.TOUCH_GAP`) is an impact of every contact that touches there
(:func:`~pinstab.solvers.impacts.impact`: Newton's restitution e on the closing contacts' normal velocities, e = 0
on those already touching, Coulomb's law on the round cone for the tangential impulses; Pinocchio's ADMM in NCP mode
to :data:`IMPACT_TOLERANCE`), and the touching contacts then take the modes of the contact complementarity problem
(:func:`~pinstab.solvers.mode_choice.choose_modes`). A closing contact whose rebound would fly shorter than
:data:`ZENO_TIME` [s] takes e = 0: resting contact (a Zeno sequence cut where its remaining flights sum to less than
that).

Joint limits (:mod:`pinstab.constraints.joint_limits`) are frictionless one-row contacts handled the same
way: an inactive limit's event function is its gap, an active one's its reaction; a limit reached with an
approaching joint is an impact (:func:`~pinstab.solvers.impacts.limit_impact`, restitution 0 by default, the
closures kept), after which every limit that touches (gap and rate at zero) is held or released as the
assignment allows whose held limits push and whose released ones do not accelerate into their bound (held
ones first), the contacts' modes chosen for it. A limit released at rest counts as reached :data:`LIMIT_SLACK` below
where it was released, so that a joint held a rounding beyond its bound does not reach it at once; one released
moving away (turned back by its impact, thrown off by another limit's) where it was reached before, so that the
impacts of two coupled limits, each throwing the other off its bound, settle (their speeds shrink by a fixed
factor from one impact to the next, until both are below TOUCH_SPEED and held) instead of each return falling a
slack further, its load's work over it keeping the chatter going for ever.

Joint frictions (:mod:`pinstab.forces.joint_friction`) are one-row entries too: a sticking one's event function is its
margin to its bound (:func:`~pinstab.solvers.joint_friction_modes.sticking_margins`), a slipping one's its velocity
along its slip (watched once faster than :data:`ARMING_SPEED`, as a contact's slip from rest); their modes are chosen
with the limits' and the contacts' (:func:`~pinstab.solvers.joint_friction_modes.choose_frictions`), a joint that
starts sticking has its velocity (below TOUCH_SPEED) set to zero, and in an impact they are free (a dry friction's
impulse is zero).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from ..constraints.joint_limits import JointLimit
from ..contact.modes import CLOSING, HOLDING, LET_GO, ContactEvent, Mode, as_tuple, stop_kind
from ..errors import ContactInfeasibleError
from ..kernels import joint_limit_rates
from ..solvers.contact_modes import GRAZING_SPEED, ModeDynamics, ModeSolution, plane_geometries, spin_name
from ..solvers.impacts import impact, limit_impact
from ..solvers.joint_friction_modes import choose_frictions, sticking_margins
from ..solvers.mode_choice import (
    CONSISTENCY,
    EVENT_SLACK,
    SLIP_SPEED,
    TOUCH_GAP,
    TOUCH_SPEED,
    Choice,
    choose_modes,
    sticking_margin,
    torque_margin,
)
from ..solvers.ncp import NcpSolver
from .adaptive import AdaptiveLoop
from .dense import Segment
from .stepping import GRID_SLACK

EVENT_TIME = 1e-12  # [s] events are located to this (bisection on the dense output)
START, GAP_CLOSED = "start", "gap closed"  # the causes of the first modes and of an impact
IMPACT_TOLERANCE = 1e-12  # [m/s] ADMM's tolerances on the impact's velocities
IMPACT_ITERATIONS = 10_000  # ADMM's iteration limit for an impact
ARMING_SPEED = 10 * SLIP_SPEED  # [m/s] see EventLoop._slip_directions
ZENO_TIME = 1e-8  # [s] a rebound that would fly shorter than this ends the bouncing: resting contact
LIMIT_SLACK = 1e-12  # [rad or m] a joint limit is reached this far beyond its bound (or where it was released)
ACTIVE = "active"  # the mode of a held joint limit (the other: separated)
LIMIT_REACHED, REACTION_ZERO = "limit reached", "reaction reached zero"
# A run whose error control keeps taking steps shorter than CRAWL_STEP [s], CRAWL_STEPS of them in a row with no
# event between, ends with ContactInfeasibleError: dynamics that fast are no rigid contact's (a slip of 1e-9 m/s,
# whose direction turns within |v| / (mu f_n / m), about 1e-11 s: 149,058 steps of 1e-11 s, 4.5 min of wall time,
# for 2.5e-6 s of simulated time; a grazing slip is now slaved to its slip acceleration, as
# :mod:`pinstab.solvers.contact_modes` says, and that box slips through); after an event the steps grow from a first
# one of 1e-11 s tenfold per step.
CRAWL_STEP, CRAWL_STEPS = 1e-9, 500
# A run whose joint limits are reached CHATTER_IMPACTS times in a row, each impact within CHATTER_GAP [s] of the last,
# ends with ContactInfeasibleError: inelastic impacts of coupled limits settle, their speeds shrinking by a fixed factor
# from one to the next (a link between bounds 1e-4 rad apart: 14 impacts over 3.2 ms, from 0.18 rad/s to below
# TOUCH_SPEED); a thousand a microsecond apart is a chatter that does not (its flights fed by the joints' loads), some
# 10 ms of wall time per impact for ever (a thousand: 10 s).
CHATTER_GAP, CHATTER_IMPACTS = 1e-6, 1000


class RunEnd(Exception):
    """Ends an event-driven run at an event: one of the kinds the loop stops on (``event``), or a contact
    problem without a solution (``error``, e.g. :class:`~pinstab.errors.PainleveError`).

    Attributes:
        t: the event's time [s]. q, v: the state there (after the switch when it stopped on an event).
        event: the event stopped on, or None. error: the failure, or None.
    """

    def __init__(self, t: float, q: np.ndarray, v: np.ndarray, event=None, error=None) -> None:
        super().__init__(f"the run ended at t = {t:.6g} s")
        self.t, self.q, self.v, self.event, self.error = t, q, v, event, error


class EventLoop(AdaptiveLoop):
    """:class:`AdaptiveLoop` over a :class:`ModeDynamics` system whose contact modes switch at events.

    Attributes:
        events: the contact and joint-limit events so far (:class:`~pinstab.contact.modes.ContactEvent`; a
            limit's ``contact`` is its name, ``panda_joint4 upper``, its force (reaction, 0, 0)).
        stop_on: the kinds of contact event (:data:`~pinstab.contact.modes.STOP_KINDS`) that end the run
            (:class:`RunEnd`), empty by default.
        active_time: each joint limit's time held so far [s], by name (to the last switch; see
            :meth:`limit_times`).
        finders: the finders of contacts from geometry
            (:class:`~pinstab.constraints.geometry_contacts.FoundContacts`, set by :meth:`find_contacts`), asked at
            every step's end: a contact
            found there that the dynamics lack is added (separated) and the step taken again; a separated one no
            longer found is dropped. Empty by default.
    """

    def __init__(self, system, stepper, grid, every, drift_limit, warned, control, dynamics: ModeDynamics):
        super().__init__(system, stepper, grid, every, drift_limit, warned, control)
        self.dynamics = dynamics
        self.events: list[ContactEvent] = []
        self.stop_on: frozenset[str] = frozenset()
        self.impacts = NcpSolver(3 * len(dynamics.contacts), IMPACT_TOLERANCE, IMPACT_ITERATIONS)
        self._reference: list[np.ndarray] = []
        self._armed = [True] * len(dynamics.frictions)  # a slip from rest is watched for its end once it is faster
        self._floors = [-LIMIT_SLACK] * len(dynamics.limits)  # where each released limit counts as reached [rad, m]
        self._gap_floors = [0.0] * len(dynamics.contacts)  # where each separated gap closes [m]
        self._since: dict[int, float] = {}  # the active limits: since when [s]
        self._crawl = 0  # accepted steps shorter than CRAWL_STEP in a row since the last event
        self._chatter: list[tuple[float, list[int]]] = []  # the limit impacts in a row CHATTER_GAP apart: t [s], limits
        self.active_time = {limit.name: 0.0 for limit in dynamics.limits}
        self._slip_armed = [True] * len(dynamics.joint_frictions)  # a joint friction's slip is watched for its end
        self.finders: list[Any] = []
        self._declared: dict[str, int] = {}  # the contacts not found from geometry: their places, by name
        self._found: set[str] = set()  # the names of the contacts found from geometry at the last step's end
        self._switching = [element for element in dynamics.model.forces if element.switches]  # grasp holds' let-go
        for element in self._switching:
            element.watch()

    def _touches(self, i: int, q: np.ndarray) -> bool:
        """Whether limit i touches at q: its gap within TOUCH_GAP of where it counts as reached."""
        return self.dynamics.limits[i].gap(q) - self._floors[i] <= TOUCH_GAP

    def start(self, q: np.ndarray, v: np.ndarray) -> None:
        """Choose the modes at the start and record them as events (cause ``start``; limits only when held)."""
        dynamics = self.dynamics
        self._floors = [_floor(limit, q) for limit in dynamics.limits]
        separated = [Mode.SEPARATED.value] * len(dynamics.limits)
        self._switch(q, v, 0.0, START, [Mode.SEPARATED.value] * len(dynamics.contacts), True, separated, [])

    def advance(self, q: np.ndarray, v: np.ndarray, start: int, stop: int) -> tuple[np.ndarray, np.ndarray, int]:
        grid, system = self.grid, self.system
        t, t_stop = grid.time(start), grid.time(stop)
        try:
            a = system.acceleration(q, v, t, 0)
            if self.step_size is None:
                self.step_size = self.initial_step(q, v, a, t)
            while t < t_stop - GRID_SLACK * grid.dt:
                h = t_stop - t if t_stop - t < self.step_size * (1 + GRID_SLACK) else self.step_size
                self._continue_slips(q, v)
                step = self.attempt(q, v, a, t, h)
                if self._refind(q, v, step.q):  # contacts found at the step's end are new: the step again with them
                    continue
                t_new = t + step.h
                a_new = system.acceleration(step.q, step.v, t_new, 0)
                segment = Segment(system.model, t, q, v, a, t_new, step.q, step.v, a_new)
                values = self.event_values(step.q, step.v, t_new)
                dip = self._limit_dip(segment)
                if np.any(values < 0.0) or dip is not None:
                    t_event = self._locate(segment, t, t_new if dip is None else dip)
                    if dip is None:
                        t_event = self._refine((q, v, a), t, t_event, t_new)
                    q_new, v_new = self.pair.attempt(q, v, t, t_event - t, a)[:2]
                    segment = Segment(
                        system.model, t, q, v, a, t_event, q_new, v_new, system.acceleration(q_new, v_new, t_event, 0)
                    )
                    self._sample_grid(segment, self.grid_between(t, t_event), q_new, v_new)
                    self.dynamics.continued = None  # the modes are chosen on the contacts' own slips
                    q_new, v_new = self._event(q_new, v_new, t_event)
                    if abs(t_event - grid.time(self.grid_index(t_event))) <= GRID_SLACK * grid.dt:
                        self.keep(self.grid_index(t_event), q_new, v_new)
                    t, q, v = t_event, q_new, v_new
                    a = system.acceleration(q, v, t, 0)
                    self._crawl = 0
                    continue
                self.keep_step(segment, t, t_new, step.q, step.v)
                self._crawl = self._crawl + 1 if step.h < CRAWL_STEP else 0
                if self._crawl >= CRAWL_STEPS:
                    raise RunEnd(t_new, step.q, step.v, error=self._crawling(step.q, step.v, t_new))
                self.step_size = self._next_step(step)
                t, q, v, a = t_new, step.q, step.v, a_new
                self._prune(q, v)
        except ContactInfeasibleError as exc:  # the modes have switched: a replay of the chunk would not be this run
            raise RunEnd(t, q, v, error=exc) from None
        finally:
            self.dynamics.continued = None
        return q, v, stop

    def find_contacts(self, finders: list[Any]) -> None:
        """Watch the contacts of ``finders`` (:attr:`finders`); the dynamics' other contacts stay, first."""
        self.finders = list(finders)
        found = {name for finder in self.finders for name in finder.order}
        self._declared = {c.name: i for i, c in enumerate(self.dynamics.contacts) if c.name not in found}

    def _refind(self, q: np.ndarray, v: np.ndarray, q_end: np.ndarray) -> bool:
        """Ask the finders of contacts from geometry (:attr:`finders`) for the contacts at a step's end ``q_end``;
        add those the dynamics lack, separated, at the step's start (q, v) (their gaps closing from where they are
        there); whether any was added: the step is then taken again, its end's events located with them."""
        if not self.finders:
            return False
        found = [contact for finder in self.finders for contact in finder.contacts(q_end, q)]
        self._found = {contact.name for contact in found}
        current = {contact.name for contact in self.dynamics.contacts}
        new = [contact for contact in found if contact.name not in current]
        if new:
            self._arrange(self.dynamics.contacts + plane_geometries(new), q, v)
        return bool(new)

    def _prune(self, q: np.ndarray, v: np.ndarray) -> None:
        """Drop the separated contacts found from geometry that were not found at the accepted step's end (q, v)."""
        if not self.finders:
            return
        dynamics = self.dynamics
        kept = [
            contact
            for contact, mode in zip(dynamics.contacts, dynamics.modes, strict=True)
            if contact.name in self._declared or contact.name in self._found or mode is not Mode.SEPARATED
        ]
        if len(kept) < len(dynamics.contacts):
            self._arrange(kept, q, v)

    def _arrange(self, contacts: list, q: np.ndarray, v: np.ndarray) -> None:
        """Take ``contacts`` (the declared ones, then those found from geometry, by finder, pair and point) as the
        dynamics' contacts at (q, v), each kept one with its state (:meth:`ModeDynamics.rearrange`)."""
        finders = {name: (k, *finder.order[name]) for k, finder in enumerate(self.finders) for name in finder.order}
        contacts = sorted(
            contacts,
            key=lambda c: (0, self._declared[c.name]) if c.name in self._declared else (1, *finders[c.name]),
        )
        dynamics = self.dynamics
        places = dynamics.rearrange(contacts)
        gaps = dynamics.kinematics(q, v).gaps
        moved = dynamics.friction_places  # the frictions' former indices
        self._armed = [True if i is None else self._armed[i] for i in moved]
        self._gap_floors = [min(0.0, gaps[k]) if i is None else self._gap_floors[i] for k, i in enumerate(places)]
        self._reference = [dynamics.directions[f] if i is None else self._reference[i] for f, i in enumerate(moved)]
        if 3 * len(contacts) > self.impacts.size:
            self.impacts = NcpSolver(3 * len(contacts), IMPACT_TOLERANCE, IMPACT_ITERATIONS)

    def _continue_slips(self, q: np.ndarray, v: np.ndarray) -> None:
        """Take the slip directions at the start of a step from (q, v) as the references of the sliding contacts' event
        functions, and continue each watched (armed) sliding mode past its end in the step: its friction keeps that
        direction once the slip turns against it (:attr:`~pinstab.solvers.contact_modes.ModeDynamics.continued`), so
        that a step across the end is smooth and the end is located on its dense output to :data:`EVENT_TIME` (with
        the friction flipping there, sphere-spin's end came out 1.4e-9 s late on a step of 2e-9 s, the slip there
        above SLIP_SPEED: the contact went on sliding backwards, its end found again 1.25e-8 s late, each time by the
        steps the error control happened to take). The continued dynamics differ from the mode's own only where the
        slip has turned, past an event the loop locates and steps again to."""
        self.dynamics.continued = None
        self._reference = self._slip_directions(q, v)
        for i, friction in enumerate(self.dynamics.joint_frictions):
            self._slip_armed[i] = self._slip_armed[i] or abs(v[friction.index_v]) > ARMING_SPEED
        self.dynamics.continued = [
            direction if armed else None for direction, armed in zip(self._reference, self._armed, strict=True)
        ]

    def _crawling(self, q: np.ndarray, v: np.ndarray, t: float) -> ContactInfeasibleError:
        """The failure of a run whose steps stayed below :data:`CRAWL_STEP` at (q, v, t), naming the contacts in
        contact (sliding ones first, slowest first) with their slip speeds."""
        dynamics = self.dynamics
        speeds = np.hypot(*dynamics.kinematics(q, v).velocities[:, 1:].T)
        touching = [i for i, mode in enumerate(dynamics.modes) if mode is not Mode.SEPARATED]
        touching.sort(key=lambda i: (dynamics.modes[i] is not Mode.SLIDING, speeds[i]))
        named = touching or list(range(len(dynamics.contacts)))
        described = ", ".join(
            f"{dynamics.contacts[i].name} {dynamics.modes[i].value} at {speeds[i]:.3g} m/s" for i in named
        )
        return ContactInfeasibleError(
            f"at t = {t:.9g} s the error control took {CRAWL_STEPS} steps in a row shorter than {CRAWL_STEP:g} s "
            f"(contacts {described}): a slip this slow turns its direction faster than the steps can follow, "
            "its end or start a stiff problem for event-driven contacts; use the time-stepping contacts "
            "(--contacts stepping, simulate(contacts='stepping'))",
            [dynamics.contacts[i].name for i in named],
            t,
        )

    def keep_step(self, segment: Segment, t: float, t_new: float, q_new: np.ndarray, v_new: np.ndarray) -> None:
        """Keep the grid samples of an accepted step."""
        inside = self.grid_between(t, t_new)
        if inside:
            self._sample_grid(segment, inside, q_new, v_new)

    def event_values(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """Each contact's event function at (q, v, t) (negative: its mode no longer holds) [m, N or m/s]."""
        dynamics = self.dynamics
        solution = dynamics.solve(q, v, t)
        contacts, forces = solution.contacts, solution.forces
        values = np.zeros(len(dynamics.contacts) + len(dynamics.spins))
        slack = _force_slack(forces)
        limits = self._limit_values(q, solution)
        margin = None
        for i, mode in enumerate(dynamics.modes):
            if mode is Mode.SEPARATED:
                values[i] = contacts.gaps[i] - self._gap_floors[i]
            elif mode is Mode.SLIDING:
                slip = float(contacts.velocities[i, 1:] @ self._reference[i]) if self._armed[i] else np.inf
                values[i] = min(forces[i, 0] + slack, slip)
            else:
                if margin is None:
                    margin = sticking_margin(dynamics, solution, dynamics.modes) + slack
                values[i] = margin
        values[len(dynamics.contacts) :] = [self._spin_value(solution, j, slack) for j in range(len(dynamics.spins))]
        return np.concatenate([values, limits, self._friction_values(v, solution), self._switch_values(q, v, t)])

    def _switch_values(self, q: np.ndarray, v: np.ndarray, t: float) -> list[float]:
        """The event functions of the force elements that switch (a grasp-hold's let-go) at (q, v, t), each evaluated
        there if its last evaluation was at another state."""
        values = []
        for element in self._switching:
            value = element.switch_value(q, t)
            if value is None:
                self.dynamics.model.forces_at(q, v, t, [element])
                value = element.switch_value(q, t)
            values.append(value)
        return values

    def _element_switch(self, q: np.ndarray, v: np.ndarray, t: float) -> str | None:
        """Switch the force elements whose event function is below zero at (q, v, t) (a grasp-hold lets go): the first
        one's cause, else None; the dynamics' state is evaluated afresh (its forces changed)."""
        causes = []
        for element, value in zip(self._switching, self._switch_values(q, v, t), strict=True):
            cause = element.switch(t) if value < 0.0 else None
            if cause is not None:
                causes.append(cause)
                self.events.append(ContactEvent(t, element.name, HOLDING, LET_GO, cause))
        if causes:
            self.dynamics.forget_state()
        return causes[0] if causes else None

    def _friction_values(self, v: np.ndarray, solution: ModeSolution) -> np.ndarray:
        """Each joint friction's event function: a sticking one's margin to its bound [N m or N], a slipping one's
        velocity along its slip [rad/s or m/s] once watched (armed; inf before)."""
        dynamics = self.dynamics
        if not dynamics.joint_frictions:
            return np.zeros(0)
        values = sticking_margins(dynamics, dynamics.joint_friction_torques(solution), EVENT_SLACK)
        for i, (friction, slip) in enumerate(zip(dynamics.joint_frictions, dynamics.slips, strict=True)):
            if slip and self._slip_armed[i]:
                values[i] = slip * v[friction.index_v]
        return values

    def _friction_cause(self, q: np.ndarray, v: np.ndarray, t: float) -> str | None:
        """``friction reached its bound at <name>`` or ``slip velocity reached zero at <name>`` for the first joint
        friction whose event function is below zero at (q, v, t), else None."""
        values = self._friction_values(v, self.dynamics.solve(q, v, t))
        for value, friction, stuck in zip(values, self.dynamics.joint_frictions, self.dynamics.stuck, strict=True):
            if value < 0.0:
                what = "friction reached its bound" if stuck else "slip velocity reached zero"
                return f"{what} at {friction.name}"
        return None

    def _spin_value(self, solution: ModeSolution, j: int, slack: float) -> float:
        """Spin j's event function in ``solution`` (``slack``: the force slack [N]): none (inf) while its contact is
        separated; sliding, its slip velocity along its reference [rad/s] (inf until armed); sticking, its margin per
        unit bound beyond the slack [N]."""
        dynamics = self.dynamics
        f = len(dynamics.contacts) + j
        friction = dynamics.frictions[f]
        if dynamics.modes[friction.contact] is Mode.SEPARATED:
            return np.inf
        if dynamics.spin_modes[j] is Mode.SLIDING:
            rates = solution.contacts.spins[friction.rows - 3 * len(dynamics.contacts)]
            return float(rates @ self._reference[f]) if self._armed[f] else np.inf
        return torque_margin(solution.loads(), friction) + slack

    def _limit_dip(self, segment: Segment) -> float | None:
        """The earliest time [s] inside the step ``segment`` at which a released joint limit's gap on the dense
        output has a minimum beyond where the limit counts as reached, or None: a joint that passes its bound and
        turns back within one step (the gap positive at both ends, which the step's end values miss; a start on the
        bound moving into it, a second link thrown by the first one's impact). A limit's coordinate on the dense
        output is ``q0_i + p_i(u)``, ``p_i`` the increment's polynomial (its 1-DOF joint's increment is additive), so
        that its minima are the roots of ``p_i'``."""
        released = [i for i, held in enumerate(self.dynamics.active) if not held]
        if not released:
            return None
        limits = [self.dynamics.limits[i] for i in released]
        gaps = np.array([limit.gap(segment.q0) - self._floors[i] for i, limit in zip(released, limits, strict=True)])
        # (degree, limits): the gap's polynomial in u but its start, the limits' rows applied to the increment's
        terms = joint_limit_rates([limit.row for limit in limits], segment.coefficients[1:])
        dips = []
        for k in np.flatnonzero(gaps < np.abs(terms).sum(axis=0)):  # else the gap stays above its floor on [0, 1]
            polynomial = np.concatenate(([gaps[k]], terms[:, k]))
            turns = np.polynomial.polynomial.polyroots(np.polynomial.polynomial.polyder(polynomial))
            turns = np.sort(turns[np.isreal(turns)].real)
            below = [u for u in turns if 0.0 < u < 1.0 and np.polynomial.polynomial.polyval(u, polynomial) < 0.0]
            if below:
                dips.append(segment.t0 + below[0] * segment.h)
        return min(dips, default=None)

    def _limit_values(self, q: np.ndarray, solution: ModeSolution) -> np.ndarray:
        """Each joint limit's event function: an active one's reaction (beyond the event slack) [N m or N], an
        inactive one's gap from where it counts as reached [rad or m]."""
        dynamics = self.dynamics
        reactions = dynamics.limit_reactions(solution)
        slack = _force_slack(reactions)
        return np.array(
            [
                reactions[i] + slack if held else limit.gap(q) - self._floors[i]
                for i, (limit, held) in enumerate(zip(dynamics.limits, dynamics.active, strict=True))
            ]
        )

    def limit_times(self, t_end: float) -> dict[str, float]:
        """How long each joint limit held so far was held up to ``t_end`` [s], by name."""
        times = dict(self.active_time)
        for i, since in self._since.items():
            times[self.dynamics.limits[i].name] += max(0.0, t_end - since)
        return {name: float(time) for name, time in times.items() if time > 0.0}

    def _slip_directions(self, q: np.ndarray, v: np.ndarray) -> list[np.ndarray]:
        """Each contact's slip direction at (q, v); a slip that started from rest is armed (its slip velocity
        reaching zero becomes an event) once faster than :data:`ARMING_SPEED`: at a cone's edge the slip starts
        at zero acceleration, and rounding would otherwise end it at once, over and over."""
        rates = self.dynamics.kinematics(q, v).rates()
        slips = [rates[friction.rows] for friction in self.dynamics.frictions]
        from_rest = self.dynamics.from_rest
        for f, slip in enumerate(slips):
            speed = math.hypot(*slip)
            self._armed[f] = self._armed[f] or speed > ARMING_SPEED
            from_rest[f] = from_rest[f] and speed < GRAZING_SPEED
        return [self.dynamics.slip_direction(f, slip) for f, slip in enumerate(slips)]

    def _locate(self, segment: Segment, t0: float, t1: float) -> float:
        """The first time in (t0, t1] [s] at which an event function turns negative (bisection)."""
        low, high = t0, t1
        while high - low > EVENT_TIME * max(1.0, abs(high)):
            middle = 0.5 * (low + high)
            if np.any(self.event_values(*segment.state(middle), middle) < 0.0):
                high = middle
            else:
                low = middle
        return high

    def _refine(self, start: tuple[np.ndarray, np.ndarray, np.ndarray], t0: float, t_event: float, t1: float) -> float:
        """The event time ``t_event`` [s] located on a step's dense output (from ``start`` = (q, v, a) at t0 [s] to
        t1 [s], its end past the event), found again on the steps from t0 themselves, to :data:`EVENT_TIME`: the first
        time at which the state of the step to it has an event function below zero. The dense output's interpolation
        error can set the event off by more than the mode choice allows (a spinning sphere's body-frame velocity,
        quintic in no coordinate: its slip's end 8.2e-9 s late at rtol 1e-12, the slip reversed there by 8.4e-8 m/s,
        above SLIP_SPEED, and the contact went on sliding backwards); a step of the pair is of its own order. The
        bracket around t_event widens fourfold per trial until it holds the crossing, then is bisected."""
        tolerance = EVENT_TIME * max(1.0, abs(t_event))

        def crossed(time: float) -> bool:
            if time <= t0:
                return False
            q, v = self.pair.attempt(*start[:2], t0, time - t0, start[2])[:2]
            return bool(np.any(self.event_values(q, v, time) < 0.0))

        width = tolerance
        if crossed(t_event):
            low, high = max(t0, t_event - width), t_event
            while crossed(low):
                width *= 4.0
                low, high = max(t0, low - width), low
        else:
            low, high = t_event, min(t1, t_event + width)
            while high < t1 and not crossed(high):
                width *= 4.0
                low, high = high, min(t1, high + width)
        while high - low > tolerance:
            middle = 0.5 * (low + high)
            if crossed(middle):
                high = middle
            else:
                low = middle
        return high

    def _event(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The switch at an event at (q, v, t): impacts of closing gaps, then the modes; returns the state after."""
        dynamics = self.dynamics
        before = [mode.value for mode in dynamics.modes]
        limits_before = [ACTIVE if held else Mode.SEPARATED.value for held in dynamics.active]
        reached = [
            i
            for i, limit in enumerate(dynamics.limits)
            if not dynamics.active[i] and limit.gap(q) <= TOUCH_GAP and limit.speed(v) < -TOUCH_SPEED
        ]
        let_go = self._element_switch(q, v, t)
        cause = LIMIT_REACHED if reached else let_go or self._reaction_zero(q, v, t) or self._friction_cause(q, v, t)
        frictions_before = self._friction_modes()
        if reached:
            self._count_chatter(q, v, t, reached)
            self._free_frictions()
            v = self._limit_impact(q, v, t, reached, limits_before)
        contacts = dynamics.kinematics(q, v)
        closing = [
            i
            for i, mode in enumerate(dynamics.modes)
            if mode is Mode.SEPARATED and contacts.gaps[i] <= TOUCH_GAP and contacts.velocities[i, 0] < -TOUCH_SPEED
        ]
        if cause is None:
            cause = GAP_CLOSED if closing else self._bound_reached(q, v, t)
        if closing:
            self._free_frictions()
            v = self._impact(q, v, t, closing, before)
        self._switch(q, v, t, cause, before, limits_before=limits_before, frictions_before=frictions_before)
        v = self._stick(v)
        self.step_size = None if closing or reached else self.step_size
        if self.step_size is None:
            self.step_size = self.initial_step(q, v, self.system.acceleration(q, v, t, 0), t)
        return q, v

    def _friction_modes(self) -> list[tuple[str, float]]:
        """Each joint friction's mode now, ``sticking``, ``sliding`` (slipping) or ``separated`` (free, in an
        impact), with its slip sign."""
        dynamics = self.dynamics
        return [
            ((Mode.STICKING if stuck else Mode.SLIDING if slip else Mode.SEPARATED).value, slip)
            for stuck, slip in zip(dynamics.stuck, dynamics.slips, strict=True)
        ]

    def _free_frictions(self) -> None:
        """Set the joint frictions free (neither sticking nor slipping) for an impact: a dry friction's impulse is
        zero."""
        count = len(self.dynamics.joint_frictions)
        self.dynamics.stuck[:], self.dynamics.slips[:] = [False] * count, [0.0] * count

    def _stick(self, v: np.ndarray) -> np.ndarray:
        """``v`` with the velocity of each sticking joint friction's joint (at rest: within TOUCH_SPEED of zero) set to
        zero: its row holds the velocity it has."""
        stuck = [f.index_v for f, held in zip(self.dynamics.joint_frictions, self.dynamics.stuck, strict=True) if held]
        if not stuck:
            return v
        v = v.copy()
        v[stuck] = 0.0
        return v

    def _bound_reached(self, q: np.ndarray, v: np.ndarray, t: float) -> str:
        """What reached its bound at an event at (q, v, t) in the modes before it, e.g. ``friction reached the
        cone at left``: a sliding contact's normal force or slip velocity, else the sticking contact nearest
        to (or beyond) its bounds, by its normal force or its friction."""
        dynamics = self.dynamics
        solution = dynamics.solve(q, v, t)
        forces, velocities = solution.forces, solution.contacts.velocities
        worst, cause = np.inf, "a contact force reached its bound"
        for i, mode in enumerate(dynamics.modes):
            name = dynamics.contacts[i].name
            if mode is Mode.SLIDING:
                if forces[i, 0] <= _force_slack(forces):
                    return f"normal force reached zero at {name}"
                if velocities[i, 1:] @ self._reference[i] <= SLIP_SPEED:  # at rest for the mode choice
                    return f"slip velocity reached zero at {name}"
            elif mode is Mode.STICKING:
                friction = dynamics.contacts[i].mu * forces[i, 0] - float(np.hypot(*forces[i, 1:]))
                if min(forces[i, 0], friction) < worst:
                    worst = min(forces[i, 0], friction)
                    what = "normal force reached zero" if forces[i, 0] <= friction else "friction reached the cone"
                    cause = f"{what} at {name}"
        rates, loads, k = solution.contacts.rates(), solution.loads(), len(dynamics.contacts)
        for j, spin in enumerate(dynamics.spins):
            friction, name = dynamics.frictions[k + j], dynamics.contacts[spin.contact].name
            if dynamics.modes[spin.contact] is Mode.SEPARATED:
                continue
            if dynamics.spin_modes[j] is Mode.SLIDING:
                if rates[friction.rows] @ self._reference[k + j] <= SLIP_SPEED:
                    return f"{spin.kind} slip reached zero at {name}"
            elif torque_margin(loads, friction) < worst:
                worst = torque_margin(loads, friction)
                cause = f"{spin.kind} reached its bound at {name}"
        return cause

    def _reaction_zero(self, q: np.ndarray, v: np.ndarray, t: float) -> str | None:
        """``reaction reached zero at <limit>`` for the active joint limit whose reaction is smallest when it is
        on its bound at (q, v, t), else None (the event is a contact's)."""
        dynamics = self.dynamics
        reactions = dynamics.limit_reactions(dynamics.solve(q, v, t))
        held = [i for i, active in enumerate(dynamics.active) if active]
        if not held:
            return None
        i = min(held, key=lambda j: reactions[j])
        return f"{REACTION_ZERO} at {dynamics.limits[i].name}" if reactions[i] <= _force_slack(reactions) else None

    def _count_chatter(self, q: np.ndarray, v: np.ndarray, t: float, reached: list[int]) -> None:
        """Count the impact of the limits ``reached`` at (q, v, t) in the chatter (see :data:`CHATTER_IMPACTS`).

        Raises:
            RunEnd: with ContactInfeasibleError, the chatter's limits named, from when and how often.
        """
        if self._chatter and t - self._chatter[-1][0] > CHATTER_GAP:
            self._chatter = []
        self._chatter.append((t, reached))
        if len(self._chatter) < CHATTER_IMPACTS:
            return
        limits = sorted({i for _, impact in self._chatter for i in impact})
        names = [self.dynamics.limits[i].name for i in limits]
        error = ContactInfeasibleError(
            f"at t = {t:.9g} s the joint limits {', '.join(names)} were reached {len(self._chatter)} times in a row "
            f"since t = {self._chatter[0][0]:.9g} s, each impact within {CHATTER_GAP:g} s of the last: a chatter "
            "that does not settle; give the joints a wider range or set the limits aside (robot.ignore_limits, "
            "--ignore-limits)",
            names,
            t,
        )
        raise RunEnd(t, q, v, error=error)

    def _limit_impact(
        self, q: np.ndarray, v: np.ndarray, t: float, reached: list[int], before: list[str]
    ) -> np.ndarray:
        """The velocity after the impact of the joint limits ``reached`` (each with its restitution) together with
        the held and touching ones (e = 0), closures kept; each limit the impulse reaches is recorded (``before`` turns
        ``closing``)."""
        dynamics = self.dynamics
        restitutions = {i: 0.0 for i, limit in enumerate(dynamics.limits) if dynamics.active[i] or self._touches(i, q)}
        restitutions.update({i: dynamics.limits[i].restitution for i in reached})
        result = limit_impact(dynamics, q, v, t, restitutions)
        for i in reached:
            limit = dynamics.limits[i]
            self.events.append(
                ContactEvent(
                    t,
                    limit.name,
                    before[i],
                    CLOSING,
                    "impact",
                    impulse=(float(result.impulses[i]), 0.0, 0.0),
                    work=float(result.impulses[i]) * (limit.speed(v) + limit.speed(result.velocity)) / 2,
                )
            )
            before[i] = CLOSING
        return result.velocity

    def _impact(self, q: np.ndarray, v: np.ndarray, t: float, closing: list[int], before: list[str]) -> np.ndarray:
        """The velocity after the impact at (q, v, t) of the ``closing`` contacts, each with its restitution (0
        when its rebound would fly shorter than :data:`ZENO_TIME`), together with every contact that touches
        (e = 0); each contact the impulse reaches is recorded (``before`` turns ``closing``)."""
        dynamics = self.dynamics
        solution = dynamics.solve(q, v, t, [Mode.SEPARATED] * len(dynamics.contacts))
        contacts = solution.contacts
        restitutions = {
            i: 0.0
            for i, mode in enumerate(dynamics.modes)
            if mode is not Mode.SEPARATED or contacts.gaps[i] <= TOUCH_GAP
        }
        for i in closing:
            restitutions[i] = self._restitution(solution, i)
        result = impact(dynamics, self.impacts, v, solution, restitutions)
        self.impacts.record(self.system.solver.statistics)
        if not self.impacts.status().converged:
            names = [dynamics.contacts[i].name for i in sorted(restitutions)]
            error = ContactInfeasibleError(
                f"at t = {t:.9g} s the impact of contacts {', '.join(names)} was not solved: "
                f"{self.impacts.failure()} m/s",
                names,
                t,
            )
            raise RunEnd(t, q, v, error=error)
        reach = np.einsum("ij,ji->i", contacts.jacobian[0::3], solution.mobility[:, 0::3])  # [m/s per N s]
        mean = (contacts.jacobian @ (v + result.velocity)).reshape(-1, 3) / 2  # each contact point's (u- + u+) / 2
        for i in sorted(restitutions):
            if i in closing or result.impulses[i, 0] * reach[i] > TOUCH_SPEED:
                work = float(result.impulses[i] @ mean[i])
                name = dynamics.contacts[i].name
                self.events.append(
                    ContactEvent(t, name, before[i], CLOSING, "impact", impulse=as_tuple(result.impulses[i]), work=work)
                )
                before[i] = CLOSING
        return result.velocity

    def _restitution(self, solution: ModeSolution, i: int) -> float:
        """Contact i's Newton's e [-] at its impact, 0 when the rebound would fly shorter than :data:`ZENO_TIME`
        under the normal acceleration without contact forces (``solution``: every contact separated)."""
        contacts, row = solution.contacts, 3 * i
        restitution = self.dynamics.contacts[i].restitution
        gravity = -(contacts.jacobian[row] @ solution.free + contacts.drift[row])
        rebound = -restitution * contacts.velocities[i, 0]
        return 0.0 if gravity > 0.0 and 2.0 * rebound / gravity < ZENO_TIME else restitution

    def _switch(
        self,
        q: np.ndarray,
        v: np.ndarray,
        t: float,
        cause: str,
        before: list[str],
        force_record: bool = False,
        limits_before: list[str] | None = None,
        frictions_before: list[tuple[str, float]] | None = None,
    ):
        dynamics = self.dynamics
        slack = CONSISTENCY if cause in (START, GAP_CLOSED, LIMIT_REACHED) else EVENT_SLACK
        try:
            choice = self._choose(q, v, t, slack, self._stopped(q, v))
        except ContactInfeasibleError as exc:  # no replay: the modes up to here are the run's
            raise RunEnd(t, q, v, error=exc) from None
        self._limit_events(q, v, t, cause, limits_before or [], choice.solution)
        self._friction_events(v, t, cause, frictions_before or [], choice.solution)
        first = len(self.events)
        contacts = choice.solution.contacts
        for f, direction in choice.directions.items():
            dynamics.directions[f] = direction
        for i, (old, new) in enumerate(zip(before, choice.modes, strict=True)):
            self._armed[i] = new is not Mode.SLIDING or float(np.hypot(*contacts.velocities[i, 1:])) > SLIP_SPEED
            dynamics.from_rest[i] = not self._armed[i]
            if new is Mode.STICKING and dynamics.modes[i] is not Mode.STICKING:
                dynamics.contacts[i].anchor = contacts.local[i].copy()
            if force_record or old != new.value:
                self.events.append(
                    ContactEvent(
                        t,
                        dynamics.contacts[i].name,
                        old,
                        new.value,
                        cause if old != CLOSING else "impact",
                        as_tuple(choice.solution.forces[i]),
                        as_tuple(contacts.velocities[i, 1:]),
                    )
                )
        self._spin_events(t, cause, before, force_record, choice)
        dynamics.modes[:] = choice.modes
        dynamics.spin_modes[:] = choice.spin_modes
        self._gap_floors = [min(0.0, gap) for gap in contacts.gaps]  # a gap closes again from where it is
        names = {contact.name for contact in dynamics.contacts}
        names |= {spin_name(dynamics.contacts[spin.contact].name, spin) for spin in dynamics.spins}
        stops = [e for e in self.events[first:] if e.contact in names and stop_kind(e) in self.stop_on]
        if stops:
            raise RunEnd(t, q, v, event=stops[0])

    def _spin_events(self, t: float, cause: str, before: list[str], force_record: bool, choice: Choice) -> None:
        """Record the spins whose mode changes at t in ``choice`` (from their contacts' modes ``before`` and their
        own): contact ``<name> <kind>`` (e.g. ``table rolling``), force (f_n [N], torque [N m]), slip velocity
        its relative angular velocity [rad/s] (padded with zeros); arm the sliding ones that spin."""
        dynamics, k = self.dynamics, len(self.dynamics.contacts)
        torques, spins = choice.solution.torques, choice.solution.contacts.spins
        for j, spin in enumerate(dynamics.spins):
            rows = dynamics.frictions[k + j].rows - 3 * k
            on_before = before[spin.contact] not in (Mode.SEPARATED.value, CLOSING)
            old = dynamics.spin_modes[j].value if on_before else Mode.SEPARATED.value
            new = choice.spin_modes[j] if choice.modes[spin.contact] is not Mode.SEPARATED else Mode.SEPARATED
            self._armed[k + j] = new is not Mode.SLIDING or math.hypot(*spins[rows]) > SLIP_SPEED
            if force_record or old != new.value:
                event_cause = "impact" if before[spin.contact] == CLOSING else cause
                force = np.zeros(3)
                force[0], force[1 : 1 + rows.size] = choice.solution.forces[spin.contact, 0], torques[rows]
                self.events.append(
                    ContactEvent(
                        t,
                        spin_name(dynamics.contacts[spin.contact].name, spin),
                        old,
                        new.value,
                        event_cause,
                        as_tuple(force),
                        as_tuple(np.pad(spins[rows], (0, 2 - rows.size))),
                    )
                )

    def _stopped(self, q: np.ndarray, v: np.ndarray) -> list[int]:
        """The sliding frictions (by index in the dynamics' frictions) whose slip may end at (q, v): watched (armed:
        they slipped faster than :data:`ARMING_SPEED`) and now slower than that (what is left of a slip located at
        its end: its velocity across the direction it had, which turns as the slip stops, 1.0 to 1.1e-9 m/s on
        allegro-tilt's ring finger); the mode choice lets them stick when no mode is consistent with them sliding."""
        dynamics = self.dynamics
        rates = dynamics.kinematics(q, v).rates()
        return [
            f
            for f, friction in enumerate(dynamics.frictions)
            if dynamics.sliding(f) and self._armed[f] and math.hypot(*rates[friction.rows]) <= ARMING_SPEED
        ]

    def _choose(self, q: np.ndarray, v: np.ndarray, t: float, slack: float, stopped: list[int]):
        """The contact modes (:func:`~pinstab.solvers.mode_choice.choose_modes`, the contacts ``stopped`` free to
        stick: :meth:`_stopped`) with the joint limits that touch
        (gap within TOUCH_GAP beyond where they count as reached, rate within TOUCH_SPEED) set to the first
        consistent assignment, held ones first, the others released (``dynamics.active`` is left at it).

        Raises:
            ContactInfeasibleError: no assignment is consistent (naming the limits).
        """
        dynamics = self.dynamics
        candidates = [
            i for i, limit in enumerate(dynamics.limits) if self._touches(i, q) and abs(limit.speed(v)) <= TOUCH_SPEED
        ]
        dynamics.active[:] = [False] * len(dynamics.limits)  # a held limit an impact set moving is released
        error: ContactInfeasibleError | None = None
        for assignment in itertools.product((True, False), repeat=len(candidates)):
            for i, held in zip(candidates, assignment, strict=True):
                dynamics.active[i] = held
            try:
                contact_modes = lambda: choose_modes(dynamics, q, v, t, slack, stopped)  # noqa: E731
                choice = choose_frictions(dynamics, v, t, slack, contact_modes)
            except ContactInfeasibleError as exc:
                error = exc
                continue
            if self._limits_consistent(choice.solution, candidates, slack):
                return choice
        if error is not None:
            raise error
        names = [dynamics.limits[i].name for i in candidates]
        raise ContactInfeasibleError(
            f"at t = {t:.9g} s no assignment of the joint limits {', '.join(names)} (held or released) is consistent",
            names,
            t,
        )

    def _limits_consistent(self, solution: ModeSolution, candidates: list[int], slack: float) -> bool:
        """Whether the held limits among ``candidates`` push and the released ones do not accelerate into their
        bound in ``solution``."""
        dynamics = self.dynamics
        reactions = dynamics.limit_reactions(solution)
        scale = 1.0 + float(np.max(np.abs(reactions), initial=0.0))
        reach = CONSISTENCY * (1.0 + float(np.max(np.abs(solution.free))))
        for i in candidates:
            limit = dynamics.limits[i]
            if dynamics.active[i] and reactions[i] < -slack * scale:
                return False
            if not dynamics.active[i] and limit.speed(solution.acceleration) < -reach:  # its row's G a
                return False
        return True

    def _limit_events(
        self, q: np.ndarray, v: np.ndarray, t: float, cause: str, before: list[str], solution: ModeSolution
    ) -> None:
        """Record the joint limits whose mode changed (from ``before``) in ``solution``'s, keep their times held
        and where a released one counts as reached again (:meth:`_release_floor`): a held one let go, or one that
        touches and is not held (stopped or turned back by an impact)."""
        dynamics = self.dynamics
        reactions = dynamics.limit_reactions(solution)
        for i, (old, held) in enumerate(zip(before, dynamics.active, strict=True)):
            new = ACTIVE if held else Mode.SEPARATED.value
            limit = dynamics.limits[i]
            if held and i not in self._since:
                self._since[i] = t
            elif not held and (i in self._since or self._touches(i, q)):
                if i in self._since:
                    self.active_time[limit.name] += t - self._since.pop(i)
                self._floors[i] = self._release_floor(i, q, v)
            if old != new and not (cause == START and not held):
                event_cause = "impact" if old == CLOSING else cause
                self.events.append(ContactEvent(t, limit.name, old, new, event_cause, (float(reactions[i]), 0.0, 0.0)))

    def _friction_events(
        self, v: np.ndarray, t: float, cause: str, before: list[tuple[str, float]], solution: ModeSolution
    ) -> None:
        """Record the joint frictions whose mode or slip sign changed from ``before`` (empty at the start: each one's
        first mode) with their torque in ``solution`` and velocity; a slip from rest is watched for its end once faster
        than :data:`ARMING_SPEED`."""
        dynamics = self.dynamics
        torques = dynamics.joint_friction_torques(solution)
        for i, (friction, new) in enumerate(zip(dynamics.joint_frictions, self._friction_modes(), strict=True)):
            speed = float(v[friction.index_v])
            self._slip_armed[i] = abs(speed) > ARMING_SPEED
            old = before[i] if before else (Mode.SEPARATED.value, 0.0)
            if old != new or not before:
                force = (float(torques[i]), 0.0, 0.0)
                self.events.append(ContactEvent(t, friction.name, old[0], new[0], cause, force, (speed, 0.0)))

    def _release_floor(self, i: int, q: np.ndarray, v: np.ndarray) -> float:
        """Where limit i, released at (q, v), counts as reached again [rad, m]. Released at rest (its rate within
        TOUCH_SPEED: a held one let go, one an impact stopped) it may lie a rounding beyond its bound, which it would
        reach again at once, over and over: :func:`_floor`. Released moving away (an impact turned it back, or
        another limit's impulse threw it off) its gap grows from here, and it is reached again where it was reached
        before (or here, if lower): a floor :data:`LIMIT_SLACK` lower at each release would let each return fall
        that much further, the work of the joint's load over it feeding a chatter between two coupled limits that
        never settles (a link between its bounds 1e-4 rad apart: 10 um/s after every impact, one impact every
        7e-7 s)."""
        limit = self.dynamics.limits[i]
        if limit.speed(v) <= TOUCH_SPEED:
            return _floor(limit, q)
        return min(self._floors[i], limit.gap(q))


def _floor(limit: JointLimit, q: np.ndarray) -> float:
    """Where a limit counts as reached [rad, m]: :data:`LIMIT_SLACK` beyond its bound, or beyond q when q is already
    past it (a start on it, a release there)."""
    return min(0.0, limit.gap(q)) - LIMIT_SLACK


def _force_slack(forces: np.ndarray) -> float:
    """How far [N] beyond a bound a force of ``forces`` (k, 3) must be for an event: :data:`EVENT_SLACK` relative,
    as :func:`~pinstab.solvers.mode_choice.choose_modes` then allows."""
    return EVENT_SLACK * (1.0 + float(np.max(np.abs(forces), initial=0.0)))
