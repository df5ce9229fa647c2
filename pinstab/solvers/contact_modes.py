"""The dynamics of contacts in given modes (:mod:`pinstab.contact.modes`): one linear solve per state.

Contact i is a point p of body a (or a sphere of radius r on it) touching a plane carried by body b (or
fixed in the world): normal n_i, basis B_i with rows (n, t1, t2), all turning with b. With w the velocity
of p relative to b's material point at p, the contact's rows are ``B_i (a_a - a_b - 2 omega_b x w)``, the
second derivative of p's position in b's frame (for a world plane: ``B_i (J_i a + c_i)``). Unknowns: the
accelerations a and the contact forces f_i = (f_n, f_t1, f_t2) on body a in B_i (body b takes the
opposite); ``M a + h = tau + sum J_i^T B_i^T f_i`` and per contact, by mode:

* sticking: ``B_i (J_i a + c_i) = -Kd B_i w - Kp e_i`` (3 rows; e_i: the gap, then the tangential
  creep from the point of b where sticking began);
* sliding: ``n.(J_i a + c_i) = -Kd n.w - Kp gap`` and ``f_t + mu f_n d = 0`` (d: the unit slip
  velocity, or while it is below :data:`SLIP_FLOOR` the direction the slip started in; in a grazing slip, the
  direction of its slip acceleration, below);
* separated: ``f_i = 0``.

With ``a = M^-1 (tau - h + W^T f)`` the rows are a 3k x 3k system in f, solved in the least-squares sense
with the smallest forces (redundant sticking contacts, e.g. a box on four corners, leave the forces
non-unique and the accelerations unique). Whether the forces can also lie inside every cone is decided by
:func:`~pinstab.solvers.mode_choice.sticking_margin` (the best margin over the forces that give the same
motion).

Grazing slip: a slip that starts from rest, at its cone's edge, turns its direction d = v_t / |v_t| at the rate
``|s_perp| / |v_t|`` (s_perp: the part of its slip acceleration s across d), within 1e-11 s at 1e-9 m/s: a stiff
direction that explicit error-controlled steps follow only at steps that short (a box pushed at mu = 5 took 149,058
steps of 1e-11 s; the run was stopped as a crawl). In the limit the direction is slaved to the slow manifold
``d x s(d) = 0``, ``d . s(d) > 0``: the slip accelerates along its own friction's direction. While a slip that
started from rest has not yet been faster than :data:`GRAZING_SPEED` and speeds up, its d is that root (Newton's
method on the angles of all such contacts at once, from the directions the slips have; a root more than
:data:`GRAZING_TURN` away from them is another motion's and is not taken), a function of the state alone; above it,
d is the slip velocity's, which the slaved slip has been accelerating along (a slip that slows down is never slaved:
its end is an event). The box now slips through to its slip ends; its state 0.022 s into the slip agrees with the
time-stepping contacts' extrapolated to dt = 0 (Richardson, from 2e-5 and 1e-5 s) to 1.3e-9 m, where each of those is
3.5e-5 m off (tests/test_contact_wall_time.py).

Bilateral rows B, always held, come first: the model's own equality constraints (loop closures: ``G a + gamma
= -Kd g - Kp phi``), the joint frictions that stick (``a_i = 0``, :mod:`pinstab.forces.joint_friction`; a slipping
one's friction is an applied torque) and the joint limits that are active (``sign a_i = -Kd sign v_i - Kp gap``,
:mod:`pinstab.constraints.joint_limits`). They are eliminated before the contacts: ``free`` and ``mobility`` are the
accelerations without contact forces and their response to them *with* B held (``a = a0 + M^-1 B^T lambda``,
``B a = beta``), so that contact modes, forces and impacts see a system whose closures, sticking frictions and active
limits hold; the reactions ``lambda`` (closure rows, sticking frictions, then active limits) are affine in the contact
forces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from ..constraints.contacts import contact_basis
from ..constraints.grasp_contacts import cross
from ..constraints.joint_limits import JointLimit
from ..contact.modes import Mode
from ..contact.round_pairs import core_nearest
from ..errors import ConstraintError, ContactInfeasibleError, SolverError
from ..forces.joint_friction import JointFriction
from ..kernels import block_jacobian, plane_contact_rows
from ..model import ConstrainedModel
from ..runinfo import SolverStatistics

SLIP_FLOOR = 1e-9  # [m/s] below this slip speed the slip direction is the one it started in
GRAZING_SPEED = 1e-5  # [m/s] a slip slower than this slides along its slip acceleration (grazing slip)
GRAZING_PASSES = 30  # Newton passes for grazing slips' directions
GRAZING_ANGLE = 1e-7  # [rad] the forward difference of a grazing direction's angle
GRAZING_TURN = 0.1  # [rad] a grazing direction this far from its slip's (or start's) is another slip's: not taken
GRAZING_RESIDUAL = 1e-12  # [-] |d x s| of a grazing slip this small, relative to the accelerations' scale: settled
RANK_TOLERANCE = 1e-12  # relative singular values of the force system below this: redundant rows
HELD_RANK_TOLERANCE = 1e-9  # relative singular values of the bilateral rows below this: redundant rows


@dataclass
class PlaneContactGeometry:
    """A body point touching a plane fixed in the world or carried by a body.

    Attributes:
        name: the contact's name. frame: the operational frame at the point. basis: rows (n, t1, t2) [-] in
        the plane's axes. origin: a point of the plane [m] in the plane's axes. mu: friction coefficient [-].
        restitution: Newton's e [-]. radius: a sphere of this radius [m] centred at the frame touches the
        plane (0: the frame's origin). plane_frame: the operational frame carrying the plane (None: the
        world's axes). anchor: where a sticking contact holds the point [m, plane's axes] (set when it
        starts sticking). core: a round pair's (:mod:`~pinstab.contact.round_pairs`): the ends (2, 3) [m, plane's
        axes] of B's core, against which the plane is re-computed at every state (None: the plane is fixed on its
        body). core_radius: B's radius [m] about its core. torsion, rolling: the rotational friction [m]
        (:class:`Spin`): the largest torque about the normal, about the tangents, per unit normal force (0: none).
    """

    name: str
    frame: int
    basis: np.ndarray
    origin: np.ndarray
    mu: float
    restitution: float
    radius: float = 0.0
    plane_frame: int | None = None
    anchor: np.ndarray = field(default_factory=lambda: np.zeros(3))
    core: np.ndarray | None = None
    core_radius: float = 0.0
    torsion: float = 0.0
    rolling: float = 0.0


class Spin(NamedTuple):
    """A contact's rotational friction, Coulomb-like: the torque ``tau`` [N m] on body a about the ``axes`` of the
    contact's basis (``(0,)``: torsion about the normal; ``(1, 2)``: rolling about the tangents) opposes the relative
    angular velocity of a and b there, ``|tau| <= bound f_n``; sticking, it holds that velocity at zero (``kind``:
    ``torsion`` or ``rolling``; ``contact``: the contact's index; ``bound`` [m])."""

    contact: int
    kind: str
    axes: tuple[int, ...]
    bound: float


def spin_name(contact: str, spin: Spin) -> str:
    """The name a spin's events carry: its contact's and its kind, ``table rolling``."""
    return f"{contact} {spin.kind}"


def rolling_contacts(contacts: list[PlaneContactGeometry]) -> list[str]:
    """The names of ``contacts`` with rolling resistance, which only event-driven contacts take (time-stepping
    contacts take torsion: :mod:`~pinstab.integration.contact_stepping`)."""
    return [contact.name for contact in contacts if contact.rolling]


def contact_spins(contacts: list[PlaneContactGeometry]) -> list[Spin]:
    """The rotational frictions of ``contacts``: each contact's torsion, then its rolling, when not zero."""
    spins = []
    for i, contact in enumerate(contacts):
        if contact.torsion > 0.0:
            spins.append(Spin(i, "torsion", (0,), contact.torsion))
        if contact.rolling > 0.0:
            spins.append(Spin(i, "rolling", (1, 2), contact.rolling))
    return spins


class Friction(NamedTuple):
    """One friction law of the contacts as the modes see it: the linear friction of contact ``contact`` (``spin``
    None: the forces (f_t1, f_t2) [N], bound mu [-]) or its rotational friction ``spin`` (the torques [N m], bound
    [m]). ``rows``: its forces' places in the force vector (each contact's (f_n, f_t1, f_t2), then every spin's
    torques), and its slip velocities' in the velocity vector (the contact points' velocities in their bases, then
    the spins' relative angular velocities); ``normal``: its contact's normal force's place."""

    contact: int
    spin: int | None
    rows: np.ndarray
    normal: int
    bound: float


def frictions(contacts: list[PlaneContactGeometry], spins: list[Spin]) -> list[Friction]:
    """Every friction law of ``contacts``: each contact's linear friction (indices 0..k-1), then each spin's."""
    linear = [Friction(i, None, np.array([3 * i + 1, 3 * i + 2]), 3 * i, c.mu) for i, c in enumerate(contacts)]
    offset, rotational = 3 * len(contacts), []
    for j, spin in enumerate(spins):
        rows = np.arange(offset, offset + len(spin.axes))
        rotational.append(Friction(spin.contact, j, rows, 3 * spin.contact, spin.bound))
        offset += len(spin.axes)
    return linear + rotational


def unit_slip(slip: np.ndarray, fallback: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """The unit direction of a slip (linear [m/s] or rotational [rad/s]), ``fallback`` while it is slower than
    :data:`SLIP_FLOOR`; with a ``reference`` (the direction a continued slip had at its step's start) that one once
    the slip has turned against it."""
    if reference is not None and float(slip @ reference) <= 0.0:
        return reference
    speed = math.hypot(*slip)
    return slip / speed if speed > SLIP_FLOOR else fallback


class ContactKinematics(NamedTuple):
    """The contacts at one state, in their bases: gaps (k,) [m], point positions (k, 3) [m, world] and in
    their plane's axes (k, 3) [m], velocities relative to the plane (k, 3) [m/s, basis], Jacobians (3k, nv)
    [basis] and drifts (3k,) [m/s^2, basis]; the spins' (:class:`Spin`) relative angular velocities (m,) [rad/s,
    basis], rows (m, nv) and drifts (m,) [rad/s^2] (their derivative in b's frame at zero acceleration)."""

    gaps: np.ndarray
    positions: np.ndarray
    local: np.ndarray
    velocities: np.ndarray
    jacobian: np.ndarray
    drift: np.ndarray
    spins: np.ndarray = np.zeros(0)
    spin_jacobian: np.ndarray = np.zeros((0, 0))
    spin_drift: np.ndarray = np.zeros(0)

    def rates(self) -> np.ndarray:
        """The velocity vector the frictions' rows index (:class:`Friction`): the contact points' (3k,), then the
        spins' (m,)."""
        return np.concatenate([self.velocities.ravel(), self.spins])


class ModeSolution(NamedTuple):
    """Accelerations [m/s^2, rad/s^2], the contact forces (k, 3) [N, basis], the free accelerations
    (without contact forces, the bilateral rows held), their response to the contact forces (nv, 3k; M^-1 W^T
    without bilateral rows), the kinematics they were computed at, and the bilateral rows' reactions (closure
    rows, sticking joint frictions, then active limits) [N, N m] (empty without bilateral rows); the spins' torques (m,)
    [N m, basis]."""

    acceleration: np.ndarray
    forces: np.ndarray
    free: np.ndarray
    mobility: np.ndarray
    contacts: ContactKinematics
    reactions: np.ndarray = np.zeros(0)
    torques: np.ndarray = np.zeros(0)

    def loads(self) -> np.ndarray:
        """The force vector the frictions' rows index (:class:`Friction`): the contact forces (3k,) [N], then the
        spins' torques (m,) [N m]."""
        return np.concatenate([self.forces.ravel(), self.torques])

    def slip_rates(self) -> np.ndarray:
        """The rates of the velocity vector of :meth:`ContactKinematics.rates` [m/s^2, rad/s^2]."""
        contacts = self.contacts
        linear = contacts.jacobian @ self.acceleration + contacts.drift
        if not contacts.spins.size:
            return linear
        return np.concatenate([linear, contacts.spin_jacobian @ self.acceleration + contacts.spin_drift])


class Bilateral(NamedTuple):
    """The bilateral rows' reactions at one state: without contact forces (b,) and per unit contact force
    (b, 3k) [N, N m per N]."""

    reactions: np.ndarray
    response: np.ndarray


class SpinResponse(NamedTuple):
    """The accelerations' response to the spins' torques (nv, m) and the bilateral rows' (b, m) (None without
    bilateral rows), at one state."""

    mobility: np.ndarray
    reactions: np.ndarray | None


class ModeDynamics:
    """Accelerations of a model whose plane contacts are in given modes.

    Args:
        model: the constrained model; its own constraints (equality rows: loop closures, joint relations) are
            held as bilateral rows. contacts: the plane contacts.
        limits: the joint limits (:mod:`pinstab.constraints.joint_limits`), each active (a bilateral row) or not.
        statistics: where its evaluations are counted (a run's solver statistics; default: its own).
        joint_frictions: the joint frictions (:mod:`pinstab.forces.joint_friction`), each sticking (a bilateral row),
            slipping (an applied torque) or free (neither: in an impact, where a dry friction's impulse is zero).

    Attributes:
        name: what a run reports as its method (``info.method``). modes: each contact's mode. spins: the contacts'
            rotational frictions (:class:`Spin`), spin_modes: each one's (sticking or sliding; none while its contact
            is separated). frictions: every friction law (:class:`Friction`: each contact's linear one, then the
            spins). directions: the slip direction each sliding friction started in ((t1, t2) for a contact's).
            from_rest: whether each friction slides in a slip that started from rest and has not yet been faster than
            :data:`GRAZING_SPEED` (the event loop keeps it; a grazing slip's direction is slaved only then: a slip
            that ends slows down from faster).
            friction_places: each friction's index before the last :meth:`rearrange`. continued: None, or each
            friction's slip direction at the start of the step being taken (None: not continued), which a sliding
            one keeps once its slip turns against it: the sliding mode continued smoothly past its end, where the
            event loop's step and dense output locate that end
            (:meth:`~pinstab.integration.events.EventLoop._continue_slips`).
            active: whether each limit is held. joint_frictions: the joint frictions; stuck: whether each sticks;
            slips: each one's slip sign s (its torque ``-friction s``; 0: none). statistics:
            the dynamics evaluations so far (states: a state solved in several modes counts once; status
            ``contact modes``), the worst relative residual of the mode's force system [-].
    """

    name = "contact-modes"  # each contact's rows of its mode solved for the forces (numpy, dense)

    def __init__(
        self,
        model: ConstrainedModel,
        contacts: list[PlaneContactGeometry],
        limits: list[JointLimit] | None = None,
        statistics: SolverStatistics | None = None,
        joint_frictions: list[JointFriction] | None = None,
    ) -> None:
        self.model = model
        self.contacts = contacts
        self.limits = list(limits or [])
        self.active = [False] * len(self.limits)
        self.joint_frictions = list(joint_frictions or [])
        self.stuck = [False] * len(self.joint_frictions)
        self.slips = [0.0] * len(self.joint_frictions)
        self.modes: list[Mode] = [Mode.SEPARATED] * len(contacts)
        self.spins = contact_spins(contacts)
        self.frictions = frictions(contacts, self.spins)
        self.spin_modes: list[Mode] = [Mode.STICKING] * len(self.spins)
        self.directions: list[np.ndarray] = [_first_direction(f) for f in self.frictions]
        self.from_rest = [False] * len(self.frictions)
        self.friction_places: list[int | None] = list(range(len(self.frictions)))
        self.continued: list[np.ndarray | None] | None = None
        self.statistics = SolverStatistics() if statistics is None else statistics
        self._redundant: dict[tuple[Mode, ...], bool] = {}
        self._state: tuple | None = None
        self._unforced_terms: tuple[np.ndarray, np.ndarray, ContactKinematics, Bilateral | None] | None = None
        self._spin_terms: SpinResponse | None = None  # the spins' response at the state of _unforced_terms
        self._planes: tuple[np.ndarray, tuple] | None = None  # plane_arrays of the contacts

    def rearrange(self, contacts: list[PlaneContactGeometry]) -> list[int | None]:
        """Take ``contacts`` as the contacts, in their order (contacts found from geometry come and go): one of the
        same name as a contact kept is that contact, with its mode, slip direction and anchor; a new one starts
        separated. Returns each one's former index (None: new)."""
        former = {contact.name: i for i, contact in enumerate(self.contacts)}
        places = [former.get(contact.name) for contact in contacts]
        old = {
            (self.contacts[f.contact].name, f.spin is None or self.spins[f.spin].kind): k
            for k, f in enumerate(self.frictions)
        }
        spin_modes = {
            (self.contacts[s.contact].name, s.kind): m for s, m in zip(self.spins, self.spin_modes, strict=True)
        }
        self.contacts = [c if i is None else self.contacts[i] for c, i in zip(contacts, places, strict=True)]
        self.modes = [Mode.SEPARATED if i is None else self.modes[i] for i in places]
        self.spins = contact_spins(self.contacts)
        self.spin_modes = [spin_modes.get((self.contacts[s.contact].name, s.kind), Mode.STICKING) for s in self.spins]
        directions, from_rest, self.frictions = self.directions, self.from_rest, frictions(self.contacts, self.spins)
        self.friction_places = [
            old.get((self.contacts[f.contact].name, f.spin is None or self.spins[f.spin].kind)) for f in self.frictions
        ]
        self.directions = [
            _first_direction(f) if k is None else directions[k]
            for f, k in zip(self.frictions, self.friction_places, strict=True)
        ]
        self.from_rest = [k is not None and from_rest[k] for k in self.friction_places]
        self.continued = None
        self._planes = None
        self._redundant.clear()  # keyed by the modes of a layout
        self._state = None
        return places

    def forget_state(self) -> None:
        """Evaluate the next state afresh (a force element switched: the same state has other forces now)."""
        self._state = None

    def kinematics(self, q: np.ndarray, v: np.ndarray) -> ContactKinematics:
        """The contacts' gaps, velocities, Jacobians and drifts at (q, v) (a full kinematics pass)."""
        self.model.kin.update(q, v)
        return self.kinematics_from_kin(v)

    def slip_direction(self, f: int, slip: np.ndarray) -> np.ndarray:
        """The unit slip direction of friction f (:attr:`frictions`) at its slip velocity ``slip`` ((t1, t2) [m/s]
        for a contact's, its spin's [rad/s]); with :attr:`continued` set, its direction there once the slip has
        turned against it (the mode continued past its end)."""
        return unit_slip(slip, self.directions[f], None if self.continued is None else self.continued[f])

    def sliding(self, f: int, modes: list[Mode] | None = None, spin_modes: list[Mode] | None = None) -> bool:
        """Whether friction f slides in ``modes`` and ``spin_modes`` (default: theirs)."""
        modes = self.modes if modes is None else modes
        friction = self.frictions[f]
        if friction.spin is None or modes[friction.contact] is Mode.SEPARATED:
            return modes[friction.contact] is Mode.SLIDING
        return (self.spin_modes if spin_modes is None else spin_modes)[friction.spin] is Mode.SLIDING

    def solve(
        self,
        q: np.ndarray,
        v: np.ndarray,
        t: float,
        modes: list[Mode] | None = None,
        spin_modes: list[Mode] | None = None,
    ) -> ModeSolution:
        """The accelerations and contact forces at (q, v, t) with the contacts in ``modes`` and their spins in
        ``spin_modes`` (default: theirs)."""
        modes = self.modes if modes is None else modes
        spin_modes = self.spin_modes if spin_modes is None else spin_modes
        free, mobility, contacts, bilateral = self._unforced(q, v, t)
        linear = 3 * len(self.contacts)
        live = [f for f in self.frictions[len(self.contacts) :] if modes[f.contact] is not Mode.SEPARATED]
        if linear == 0:
            reactions = np.zeros(0) if bilateral is None else bilateral.reactions
            return ModeSolution(free, np.zeros((0, 3)), free, mobility, contacts, reactions)
        # the force system's unknowns: the contact forces, then the torques of the spins whose contacts touch
        index = np.concatenate([np.arange(linear), *(f.rows for f in live)])
        size = index.size
        local = np.zeros(linear + contacts.spins.size, dtype=int)
        local[index] = np.arange(size)
        system, rhs = np.zeros((size, size)), np.zeros(size)
        if not live:
            delassus = contacts.jacobian @ mobility
            reach = contacts.jacobian @ free + contacts.drift  # the contact accelerations without forces
        else:
            spun = self._spin_terms
            rows_all = np.vstack([contacts.jacobian, contacts.spin_jacobian])[index]
            delassus = rows_all @ np.hstack([mobility, spun.mobility])[:, index]
            reach = rows_all @ free + np.concatenate([contacts.drift, contacts.spin_drift])[index]
        velocities, turning = contacts.rates(), {f.spin for f in live}
        for i, mode in enumerate(modes):
            rows = slice(3 * i, 3 * i + 3)
            if mode is Mode.SEPARATED:
                system[rows, rows] = np.eye(3)
            elif mode is Mode.STICKING:
                system[rows] = delassus[rows]
                rhs[rows] = -reach[rows]
            else:
                system[3 * i] = delassus[3 * i]
                rhs[3 * i] = -reach[3 * i]
        for f, friction in enumerate(self.frictions):
            if modes[friction.contact] is not Mode.SLIDING if friction.spin is None else friction.spin not in turning:
                continue
            rows = local[friction.rows]
            if friction.spin is not None and spin_modes[friction.spin] is Mode.STICKING:
                system[rows] = delassus[rows]
                rhs[rows] = -reach[rows]
            else:  # sliding: f + bound f_n d = 0
                system[np.ix_(rows, rows)] = np.eye(rows.size)
                system[rows, friction.normal] = friction.bound * self.slip_direction(f, velocities[friction.rows])
        key = (*modes, *spin_modes)
        if key not in self._redundant:  # the rank of the rows: fixed by the modes and the contacts' layout
            self._redundant[key] = not np.linalg.cond(system) < 1.0 / RANK_TOLERANCE
        forces = _forces(system, rhs, self._redundant[key])
        grazing = self._grazing(modes, velocities, system, (delassus, reach), forces)
        if grazing:
            forces = self._follow_slip_acceleration(
                system, rhs, self._redundant[key], (delassus, reach), forces, grazing
            )
        self._measure(system, forces, rhs)
        if not np.isfinite(forces).all():
            names = ", ".join(c.name for c, m in zip(self.contacts, modes, strict=True) if m is not Mode.SEPARATED)
            raise ContactInfeasibleError(
                f"at t = {t:.9g} s the forces of contacts {names} in modes "
                f"{', '.join(m.value for m in modes)} are not finite (a force system at a Painleve bound)",
                [c.name for c in self.contacts],
                t,
            )
        if not live:
            acceleration = free + mobility @ forces
            reactions = np.zeros(0) if bilateral is None else bilateral.reactions + bilateral.response @ forces
            torques = np.zeros(contacts.spins.size)
        else:
            loads = np.zeros(local.size)
            loads[index] = forces
            forces, torques = loads[:linear], loads[linear:]
            acceleration = free + mobility @ forces + spun.mobility @ torques
            reactions = np.zeros(0)
            if bilateral is not None:
                reactions = bilateral.reactions + bilateral.response @ forces + spun.reactions @ torques
        return ModeSolution(acceleration, forces.reshape(-1, 3), free, mobility, contacts, reactions, torques)

    def _grazing(
        self,
        modes: list[Mode],
        velocities: np.ndarray,
        system: np.ndarray,
        slip_rows: tuple[np.ndarray, np.ndarray],
        forces: np.ndarray,
    ) -> list[int]:
        """The sliding contacts' frictions (linear, mu > 0) in a grazing slip: started from rest and not yet faster
        than :data:`GRAZING_SPEED` (:attr:`from_rest`), speeding up along the direction the force ``system`` gives
        them (their slip acceleration ``D f + r``, ``slip_rows`` = (D, r) at ``forces``, has a positive component
        along it: a slip that slows down ends, an event), and not turned against the direction it had at the step's
        start (a slip ending within the step: the event loop locates its end). The slip acceleration is computed
        only for the frictions that pass the other tests (most evaluations have none)."""
        delassus, reach = slip_rows
        grazing = []
        for f, friction in enumerate(self.frictions[: len(self.contacts)]):
            slip, rows = velocities[friction.rows], friction.rows
            continued = None if self.continued is None else self.continued[f]
            if (
                self.from_rest[f]
                and modes[friction.contact] is Mode.SLIDING
                and friction.bound > 0.0
                and math.hypot(*slip) < GRAZING_SPEED
                and (continued is None or float(slip @ continued) > 0.0)
                and float((delassus[rows] @ forces + reach[rows]) @ system[rows, friction.normal]) > 0.0
            ):
                grazing.append(f)
        return grazing

    def _follow_slip_acceleration(
        self,
        system: np.ndarray,
        rhs: np.ndarray,
        redundant: bool,
        slip_rows: tuple[np.ndarray, np.ndarray],
        forces: np.ndarray,
        grazing: list[int],
    ) -> np.ndarray:
        """The forces with the grazing frictions' directions slaved to their slip accelerations (module docstring:
        grazing slip): the angles of the directions d at which each one's slip acceleration ``s = D f + r``
        (``slip_rows`` = (D, r): :meth:`solve`'s delassus and reach) is parallel to d, ``d x s = 0`` for all at once,
        by Newton's method on the angles (Jacobian by forward differences of :data:`GRAZING_ANGLE` [rad]) from the
        directions ``system`` holds, to ``|d x s|`` within :data:`GRAZING_RESIDUAL` of the free accelerations'
        scale, in at most :data:`GRAZING_PASSES` passes. Where the root's slip accelerations do not all point along
        their slips (``d . s <= 0``: a slip that decelerates, whose end is an event) or no root is found, the forces
        of the directions given (``forces``; ``system`` restored)."""
        delassus, reach = slip_rows
        given = [system[self.frictions[f].rows, self.frictions[f].normal].copy() for f in grazing]
        start = np.array([math.atan2(d[1], d[0]) for d in given])
        angles = start.copy()
        scale = GRAZING_RESIDUAL * (1.0 + float(np.max(np.abs(reach))))

        def residuals(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            turns = np.column_stack([np.cos(angles), np.sin(angles)])
            for f, d in zip(grazing, turns, strict=True):
                system[self.frictions[f].rows, self.frictions[f].normal] = self.frictions[f].bound * d
            solved = _forces(system, rhs, redundant)
            rates = np.array(
                [delassus[self.frictions[f].rows] @ solved + reach[self.frictions[f].rows] for f in grazing]
            )
            return turns[:, 0] * rates[:, 1] - turns[:, 1] * rates[:, 0], np.sum(turns * rates, axis=1), solved

        for _ in range(GRAZING_PASSES):
            across, along, solved = residuals(angles)
            if not np.all(np.isfinite(across)):
                break
            if np.max(np.abs(across)) <= scale:
                if np.all(along > 0.0) and np.max(np.abs(angles - start)) <= GRAZING_TURN:
                    return solved
                break
            steps = np.eye(angles.size) * GRAZING_ANGLE
            jacobian = np.column_stack([(residuals(angles + step)[0] - across) / GRAZING_ANGLE for step in steps])
            try:
                angles = angles - np.linalg.solve(jacobian, across)
            except np.linalg.LinAlgError:
                break
        for f, d in zip(grazing, given, strict=True):
            system[self.frictions[f].rows, self.frictions[f].normal] = d
        return forces

    def _measure(self, system: np.ndarray, forces: np.ndarray, rhs: np.ndarray) -> None:
        """The force system's residual ``|system f - rhs|`` relative to its terms' size [-] into the statistics'
        worst (a least-squares solve of redundant rows leaves one where the rows disagree)."""
        scale = max(np.linalg.norm(rhs), np.linalg.norm(system) * np.linalg.norm(forces), np.finfo(float).tiny)
        residual = np.linalg.norm(system @ forces - rhs) / scale
        if math.isfinite(residual):
            self.statistics.worst_primal_residual = max(self.statistics.worst_primal_residual, float(residual))

    def limit_reactions(self, solution: ModeSolution) -> np.ndarray:
        """Each limit's reaction in ``solution`` [N m or N], positive when it pushes away from its bound (zero for
        the limits not active)."""
        reactions = np.zeros(len(self.limits))
        active = [i for i, held in enumerate(self.active) if held]
        if active:
            reactions[active] = solution.reactions[solution.reactions.size - len(active) :]
        return reactions

    def joint_friction_torques(self, solution: ModeSolution) -> np.ndarray:
        """Each joint friction's torque in ``solution`` [N m or N]: a sticking one's reaction, a slipping one's
        ``-friction s``."""
        torques = np.array([-f.friction * s for f, s in zip(self.joint_frictions, self.slips, strict=True)])
        stuck = [i for i, held in enumerate(self.stuck) if held]
        if stuck:
            end = solution.reactions.size - sum(self.active)
            torques[stuck] = solution.reactions[end - len(stuck) : end]
        return torques

    def slip_torque(self) -> np.ndarray:
        """The slipping joint frictions' generalized force [N m or N] (nv,)."""
        tau = np.zeros(self.model.nv)
        for friction, slip in zip(self.joint_frictions, self.slips, strict=True):
            tau[friction.index_v] -= friction.friction * slip
        return tau

    def one_rows(self) -> list:
        """The one-row bilateral entries held now, each with a compiled ``row``: the sticking joint frictions, then
        the active limits."""
        frictions = [f for f, held in zip(self.joint_frictions, self.stuck, strict=True) if held]
        return frictions + [limit for limit, held in zip(self.limits, self.active, strict=True) if held]

    def bilateral_rows(self, terms, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The bilateral rows at (q, v) (``terms``: :meth:`ConstrainedModel.dynamics_terms` there): their Jacobian
        B (b, nv), velocity residual (b,) [m/s, rad/s] and acceleration target ``beta`` (b,) [m/s^2, rad/s^2]
        (closure rows, then the sticking frictions and the active limits: :meth:`one_rows`)."""
        values = terms.values
        held = self.one_rows()
        rows = np.zeros((len(held), self.model.nv))
        for r, entry in enumerate(held):  # the core's row (its Jacobian reads no pass of the Data)
            rows[r] = block_jacobian(self.model.model, self.model.scratch, entry.row, 0.0)[0]
        jacobian = np.vstack([values.jacobian, rows])
        velocity = np.concatenate([values.velocity_residual, rows @ v])
        target = np.concatenate([-values.drift, np.zeros(len(held))])
        return jacobian, velocity, target

    def mode_key(self) -> tuple:
        """What the unforced terms depend on besides the state: the limits held, the frictions' modes."""
        return tuple(self.active), tuple(self.stuck), tuple(self.slips)

    def _unforced(
        self, q: np.ndarray, v: np.ndarray, t: float
    ) -> tuple[np.ndarray, np.ndarray, ContactKinematics, Bilateral | None]:
        """The accelerations without contact forces, their response to them (M^-1 W^T without bilateral rows),
        the contacts and the bilateral rows' reactions at (q, v, t); the last state's are kept, as choosing modes
        solves one state in many of them (applied forces may cost a QP each)."""
        key = (t, q.tobytes(), v.tobytes(), self.mode_key())
        if key != self._state:
            self.statistics.record("contact modes", 0, math.nan, math.nan)
            terms = self.model.dynamics_terms(q, v, t)
            contacts = self.kinematics_from_kin(v)
            tau = terms.tau + self.slip_torque() if self.joint_frictions else terms.tau
            columns = [tau - terms.bias, contacts.jacobian.T]
            self._spin_terms = None
            if not self.model.constraints.rows and not self.one_rows():
                solved = self._mass_solve(terms.mass_matrix, np.column_stack(columns), t)
                if contacts.spins.size:  # a solve of its own: the contacts' columns as without spins, to the bit
                    spun = self._mass_solve(terms.mass_matrix, contacts.spin_jacobian.T, t)
                    self._spin_terms = SpinResponse(spun, None)
                self._state, self._unforced_terms = key, (solved[:, 0], solved[:, 1:], contacts, None)
                return self._unforced_terms
            jacobian, _, target = self.bilateral_rows(terms, q, v)
            targets = np.column_stack([target, np.zeros((jacobian.shape[0], contacts.jacobian.shape[0]))])
            response, reactions = self._held(terms.mass_matrix, jacobian, np.column_stack(columns), targets, t)
            bilateral = Bilateral(reactions[:, 0], reactions[:, 1:])
            if contacts.spins.size:
                targets = np.zeros((jacobian.shape[0], contacts.spins.size))
                self._spin_terms = SpinResponse(
                    *self._held(terms.mass_matrix, jacobian, contacts.spin_jacobian.T, targets, t)
                )
            self._state, self._unforced_terms = key, (response[:, 0], response[:, 1:], contacts, bilateral)
        return self._unforced_terms

    def _held(
        self, mass_matrix: np.ndarray, jacobian: np.ndarray, columns: np.ndarray, targets: np.ndarray, t: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The accelerations' response to the generalized forces ``columns`` (nv, c) with the bilateral rows
        ``jacobian`` (b, nv) held at ``targets`` (b, c): ``B (unheld + held lambda) = targets``; and the rows'
        reactions lambda (b, c). Solved through the rows' own SVD B = U S V^T (rank at :data:`HELD_RANK_TOLERANCE`):
        a = V S^-1 U^T targets + N z on B's range and null space N, with N^T M N z = N^T (columns - M a_range); not
        through the Delassus matrix B M^-1 B^T, whose condition squares theirs (Cassie's shin-spring triangles, 2e-7
        from singular: its least squares dropped their rows and the knee springs folded)."""
        u, sigma, vt = np.linalg.svd(jacobian)
        rank = int(np.sum(sigma > HELD_RANK_TOLERANCE * sigma[0])) if sigma.size else 0
        u, sigma, across, null = u[:, :rank], sigma[:rank], vt[:rank].T, vt[rank:].T
        ranged = across @ ((u.T @ targets) / sigma[:, None])
        along = self._mass_solve(null.T @ mass_matrix @ null, null.T @ (columns - mass_matrix @ ranged), t)
        response = ranged + null @ along
        return response, u @ ((across.T @ (mass_matrix @ response - columns)) / sigma[:, None])

    def _mass_solve(self, mass_matrix: np.ndarray, rhs: np.ndarray, t: float) -> np.ndarray:
        """``M^-1 rhs`` at time ``t`` [s].

        Raises:
            SolverError: a singular mass matrix, naming the contacts and the time (not numpy's LinAlgError).
        """
        try:
            return np.linalg.solve(mass_matrix, rhs)
        except np.linalg.LinAlgError as exc:
            names = ", ".join(contact.name for contact in self.contacts)
            raise SolverError(
                f"contacts {names} at t = {t:.6g} s: the mass matrix is singular ({exc}); a body of the scene has "
                "no mass or inertia in some direction"
            ) from None

    def kinematics_from_kin(self, v: np.ndarray) -> ContactKinematics:
        """:meth:`kinematics` from the pass :meth:`ConstrainedModel.dynamics_terms` just made (the plane contacts'
        rows compiled, :func:`~pinstab.kernels.plane_contact_rows`; a round pair's here, :func:`_round_rows`)."""
        kin = self.model.kin
        k = len(self.contacts)
        if self._planes is None:
            self._planes = plane_arrays(self.contacts)
        places, arrays = self._planes
        planar = plane_contact_rows(kin.model, kin.data, *arrays, v)
        if places.size == k:
            gaps, positions, local, velocities, jacobian, drift, world = planar
        else:  # round pairs among them, in their places
            gaps, positions, local, velocities = np.zeros(k), np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, 3))
            jacobian, drift, world = np.zeros((3 * k, self.model.nv)), np.zeros(3 * k), np.zeros((3 * k, 3))
            rows = (3 * places[:, None] + np.arange(3)).ravel()
            gaps[places], positions[places], local[places], velocities[places] = planar[:4]
            jacobian[rows], drift[rows], world[rows] = planar[4:]
            for i, contact in enumerate(self.contacts):
                if contact.core is not None:
                    rows = slice(3 * i, 3 * i + 3)
                    gaps[i], positions[i], jacobian[rows], drift[rows], world[rows] = _round_rows(kin, contact, v)
                    local[i] = kin.placement(contact.plane_frame).actInv(positions[i])
                    velocities[i] = jacobian[rows] @ v
        finite = np.isfinite(gaps[places])
        if not finite.all():
            i = int(places[np.argmin(finite)])  # the first not finite
            raise ConstraintError(
                f"contact {self.contacts[i].name}: its gap is {gaps[i]} (the state is not finite: q has "
                f"{np.count_nonzero(~np.isfinite(self.model.kin.q))} non-finite entries)"
            )
        bases = world.reshape(-1, 3, 3)  # (n, t1, t2) in world axes
        if not self.spins:
            return ContactKinematics(gaps, positions, local, velocities, jacobian, drift)
        spin_rows = [np.zeros((0, self.model.nv))]
        spin_drifts = [np.zeros(0)]
        for spin in self.spins:
            axes = bases[spin.contact][list(spin.axes)]
            relative, relative_drift = _spin_rows(kin, self.contacts[spin.contact], v)
            spin_rows.append(axes @ relative)
            spin_drifts.append(axes @ relative_drift)
        spin_jacobian = np.vstack(spin_rows)
        spins = spin_jacobian @ v
        return ContactKinematics(
            gaps, positions, local, velocities, jacobian, drift, spins, spin_jacobian, np.concatenate(spin_drifts)
        )

    def acceleration(self, q: np.ndarray, v: np.ndarray, t: float, stage: int = 0) -> np.ndarray:
        """The accelerations at (q, v, t) in the current modes [m/s^2, rad/s^2] (the integrators' call)."""
        return self.solve(q, v, t).acceleration


def plane_arrays(contacts: list[PlaneContactGeometry]) -> tuple[np.ndarray, tuple]:
    """The places of ``contacts`` without a core (not round pairs) and their compiled form for
    :func:`~pinstab.kernels.plane_contact_rows`: frames, plane frames (-1: the world), radii [m], bases (3k x 3) and
    plane points (k x 3) [m]."""
    places = np.array([i for i, contact in enumerate(contacts) if contact.core is None], dtype=int)
    chosen = [contacts[i] for i in places]
    return places, (
        np.array([contact.frame for contact in chosen], dtype=np.int32),
        np.array([-1 if c.plane_frame is None else c.plane_frame for c in chosen], dtype=np.int32),
        np.array([contact.radius for contact in chosen], dtype=float),
        np.array([contact.basis for contact in chosen], dtype=float).reshape(-1, 3),
        np.array([contact.origin for contact in chosen], dtype=float).reshape(-1, 3),
    )


def _relative(
    kin, plane_frame: int, point: np.ndarray, v: np.ndarray, jacobian: np.ndarray, drift: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The Jacobian (3, nv) and drift [m/s^2] of a point's motion relative to the body carrying
    ``plane_frame``, in world axes: its velocity w = v_p - v_b(p) and ``a_p - a_b(p) - 2 omega_b x w``
    (the second derivative of its position in the body's frame, turned to world axes)."""
    body_jacobian, body_drift = kin.jacobian(plane_frame), kin.drift_acceleration(plane_frame)
    arm = point - kin.placement(plane_frame).translation
    omega = body_jacobian[3:] @ v
    carried = body_jacobian[:3] - pin.skew(arm) @ body_jacobian[3:]  # v_b(p) = v_o + omega x arm
    relative = jacobian - carried
    w = relative @ v
    spin = pin.skew(omega)
    carried_drift = body_drift.linear + pin.skew(body_drift.angular) @ arm + spin @ (spin @ arm)
    return relative, drift - carried_drift - 2.0 * spin @ w


def _spin_rows(kin, contact: PlaneContactGeometry, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows (3, nv) [world axes] of the angular velocity of body a (``contact.frame``) relative to body b (its
    plane's, or the world) and their drift [rad/s^2]: the derivative in b's frame at zero acceleration, ``Omega'_B =
    alpha_a - alpha_b - omega_b x Omega``."""
    frame_jacobian, frame_drift = kin.jacobian(contact.frame)[3:], kin.drift_acceleration(contact.frame).angular
    if contact.plane_frame is None:
        return frame_jacobian, frame_drift
    body_jacobian = kin.jacobian(contact.plane_frame)[3:]
    relative = frame_jacobian - body_jacobian
    spin_drift = frame_drift - kin.drift_acceleration(contact.plane_frame).angular
    return relative, spin_drift - cross(body_jacobian @ v, relative @ v)


def _round_rows(
    kin, contact: PlaneContactGeometry, v: np.ndarray
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A round pair's gap [m], contact point [m, world], rows (3, nv), drifts (3,) [m/s^2] and basis (n, t1, t2)
    [world axes] at the state of ``kin``, n along the line from B's core to A's centre x
    (:mod:`~pinstab.contact.round_pairs`),
    t1 the first tangent of ``contact.basis`` (fixed in B's frame: where the contact was found) made normal to n
    (continuous while n turns less than 90 degrees towards it; a tangent chosen from n alone jumps where it switches
    axes, and with it a slip's direction). In B's frame (world axes), with w the velocity of x relative to B and
    H = (P - n n^T) / |x - c| the gap's Hessian: the normal row is the gap's second derivative, ``n . x''_B +
    w^T H w``; the tangent rows that of the slip ``s = w + r_a n x (omega_a - omega_b)`` (the relative velocity of
    the two surfaces' material points at the contact point), whose derivative in B's frame is
    ``x''_B + r_a (H w) x Omega + r_a n x Omega'_B``."""
    plane = kin.placement(contact.plane_frame)
    centre = kin.placement(contact.frame).translation
    nearest, projector = core_nearest(centre, (plane.rotation @ contact.core.T).T + plane.translation)
    distance = float(np.linalg.norm(centre - nearest))
    normal = (centre - nearest) / distance
    helper = plane.rotation @ contact.basis[1]
    first = helper - (helper @ normal) * normal
    first /= np.linalg.norm(first)
    basis = np.array([normal, first, cross(normal, first)])
    frame_jacobian, frame_drift = kin.jacobian(contact.frame), kin.drift_acceleration(contact.frame)
    relative, relative_drift = _relative(kin, contact.plane_frame, centre, v, frame_jacobian[:3], frame_drift.linear)
    w = relative @ v
    turn = (projector @ w - normal * (normal @ w)) / distance  # n's rate in B's frame: H w
    spin_jacobian, spin_drift = _spin_rows(kin, contact, v)  # Omega and Omega'_B at zero acceleration
    spin = spin_jacobian @ v
    arm = contact.radius * pin.skew(normal)  # r_a n x .
    slip_drift = relative_drift + contact.radius * cross(turn, spin) + arm @ spin_drift
    drift = basis @ slip_drift
    drift[0] = normal @ relative_drift + w @ turn
    gap = distance - contact.radius - contact.core_radius
    return gap, centre - contact.radius * normal, basis @ (relative + arm @ spin_jacobian), drift, basis


def _first_direction(friction: Friction) -> np.ndarray:
    """The slip direction a friction law keeps until it first slips: its first axis."""
    return np.eye(friction.rows.size)[0]


def _forces(system: np.ndarray, rhs: np.ndarray, redundant: bool) -> np.ndarray:
    """The smallest x minimizing |system x - rhs| (redundant rows give a singular system: least squares, refined
    once on its residual: a stack of three boxes on twelve corners turned 1.2e-10 rad in 10 s at rest under the
    first solve's rounding, 8e-12 refined); NaN where no finite solution is found."""
    try:
        if not redundant:
            return np.linalg.solve(system, rhs)
    except np.linalg.LinAlgError:
        pass
    try:
        forces = np.linalg.lstsq(system, rhs, rcond=RANK_TOLERANCE)[0]
        return forces + np.linalg.lstsq(system, rhs - system @ forces, rcond=RANK_TOLERANCE)[0]
    except np.linalg.LinAlgError:  # SVD did not converge: non-finite entries
        return np.full(rhs.shape, np.nan)


EVENT_GRASP_MODELS = ("point-friction", "frictionless", "soft-finger")  # grasp models with event-driven modes


def modeless_contacts(constraints: list) -> list:
    """The grasp contacts among ``constraints`` whose model has no event-driven modes (not in
    :data:`EVENT_GRASP_MODELS`): they are held as constraint rows, never switched."""
    from ..constraints import FingertipContact

    return [c for c in constraints if isinstance(c, FingertipContact) and c.model not in EVENT_GRASP_MODELS]


def plane_geometries(constraints: list) -> list[PlaneContactGeometry]:
    """The unilateral contacts among a scene's constraints as geometries for the event-driven dynamics: plane
    contacts (their ``torsion`` and ``rolling``), and grasp contacts (the fingertip's point at C on the object's tangent
    plane at C, carried by the object: exact for the motion while the contact sticks and its first slip; a sliding
    fingertip is followed on that plane, not on the curved surface; with ``surface = "round"`` the fingertip sphere on
    the sphere object, a round pair re-computed at every state; a soft finger's ``torsion`` its spin's bound).

    Raises:
        ConstraintError: a grasp contact whose model has no event-driven modes (naming the valid ones).
    """
    from ..constraints import FingertipContact, PointContact

    modeless = modeless_contacts(constraints)
    if modeless:
        raise ConstraintError(
            f"grasp contact {modeless[0].name} is {modeless[0].model}: event-driven contacts take the models "
            f"{', '.join(EVENT_GRASP_MODELS)}; hold it as constraint rows (contacts None / --contacts held)"
        )
    geometries = []
    for constraint in constraints:
        if isinstance(constraint, PointContact):
            basis = contact_basis(constraint.selection[0])
            mu = 0.0 if constraint.friction is None else constraint.friction.mu
            geometries.append(
                PlaneContactGeometry(
                    constraint.name,
                    constraint.frame_a,
                    basis,
                    constraint.plane_point.copy(),
                    mu,
                    constraint.restitution,
                    constraint.radius,
                    constraint.plane_frame,
                    core=constraint.core,
                    core_radius=constraint.core_radius,
                    torsion=constraint.torsion,
                    rolling=constraint.rolling,
                )
            )
        elif isinstance(constraint, FingertipContact):
            outward = contact_basis(np.array([0.0, 0.0, -1.0]))  # C's z points into the object
            mu = 0.0 if constraint.model == "frictionless" else constraint.mu
            torsion = constraint.torsion if constraint.model == "soft-finger" else 0.0
            surface = constraint.round
            if surface is not None:  # the fingertip sphere on the sphere object, a round pair
                geometries.append(
                    PlaneContactGeometry(
                        constraint.name,
                        surface.tip_frame,
                        contact_basis(surface.normal),
                        np.zeros(3),
                        mu,
                        0.0,
                        constraint.radius,
                        surface.object_frame,
                        core=np.array([surface.centre, surface.centre]),
                        core_radius=surface.radius,
                        torsion=torsion,
                    )
                )
                continue
            geometries.append(
                PlaneContactGeometry(
                    constraint.name,
                    constraint.finger_frame,
                    outward,
                    np.zeros(3),
                    mu,
                    0.0,
                    0.0,
                    constraint.object_frame,
                    torsion=torsion,
                )
            )
    return geometries
