"""A time-stepping loop over Pinocchio 4.1's ADMM in NCP mode for contacts that open, close, stick, slide
and impact: the peer of ``benchmarks/contacts``.

Each step (Moreau--Jean, velocity level, step ``dt``): one Pinocchio pass (:meth:`AdmmContactPeer.terms`)
gives the gaps (the normal components of the contacts' errors, a ball's measured at its lowest point),
their normal velocities ``v_n``, J, M and h; the free velocity is ``v_free = v + dt M^-1 (tau - h)``. A
contact takes part in the step when its predicted gap ``gap + theta dt v_n`` is at most ``margin`` (``theta``
= 1/2; the margin, 1e-9 m, keeps a sticking contact whose gap rounding made 1e-16 m positive);
the impulses p of those contacts solve ADMM's NCP (the exact round cone, ``solve_ncp``)
``D p + g in K*, p in K`` with ``g = J v_free`` plus, on each normal row, the larger of Newton's impact
law (the post-impact normal velocity at least ``-e v_n``) and the removal of a fraction ``erp`` of any
penetration: ``min(e min(v_n, 0), (erp / dt) min(gap, 0))`` (the two added would bounce a ball that
sank in higher than it fell). Then ``v <- v_free + M^-1 J^T p`` and
``q <- q (+) dt v``, the free bodies on R^3 x SO(3) (:class:`FreeBodies`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..constraints import PointContact
from ..constraints.contacts import contact_basis
from ..errors import PinstabError
from ..scene import Scene
from .admm_peer import (
    PLANE_ORDER,
    AdmmContactPeer,
    PeerContact,
    PeerRun,
    SolveStatistics,
    mass_solves,
    plane_contact,
    run_loop,
)
from .contact_scenes import PINCH_BLOCK, PINCH_FINGER_MASS


@dataclass(frozen=True)
class SteppingSettings:
    """The loop's settings.

    Attributes:
        dt: step [s]. erp: the fraction of a penetration removed per step [-].
        theta: the weight of the normal velocity in the predicted gap [-].
        margin: the predicted gap [m] below which a contact takes part in a step.
        tolerance: ADMM's absolute and relative feasibility and complementarity tolerances.
    """

    dt: float
    erp: float = 0.2
    theta: float = 0.5
    margin: float = 1e-9
    tolerance: float = 1e-12


@dataclass(frozen=True)
class ContactProblem:
    """A Pinocchio model with its contacts, the applied forces and the start.

    Attributes:
        model: Pinocchio's model (gravity in it). contacts: its contacts (a plane contact's c1 axes
            (t1, t2, n), a block's face likewise). restitution: Newton's e per contact [-].
        tau: the constant applied generalized forces [N, N m]. q0, v0: the start.
    """

    model: pin.Model
    contacts: list[PeerContact]
    restitution: np.ndarray
    tau: np.ndarray
    q0: np.ndarray
    v0: np.ndarray


def scene_problem(scene: Scene) -> ContactProblem:
    """A scene whose constraints are plane contacts (frictionless ones taken as mu = 0), no forces.

    Raises:
        PinstabError: another constraint, or a force element.
    """
    others = [c.name for c in scene.constraints if not isinstance(c, PointContact)]
    if others or scene.forces:
        names = others + [element.name for element in scene.forces]
        raise PinstabError(
            f"ADMM contact loop: scene {scene.name} has {', '.join(names)}; it takes plane contacts only"
        )
    contacts = [plane_contact(scene.model, c, frictionless=True) for c in scene.constraints]
    restitution = np.array([c.restitution for c in scene.constraints])
    return ContactProblem(scene.model, contacts, restitution, np.zeros(scene.model.nv), scene.q0, scene.v0)


def pinch_problem(mu: float, squeeze: float, mass: float) -> ContactProblem:
    """pinch built in Pinocchio: a free cube of side PINCH_BLOCK and ``mass`` [kg] (gravity -z), two
    PINCH_FINGER_MASS fingers on prismatic joints along x touching the centres of its faces x = -+ side/2,
    each pushed toward it with ``squeeze`` [N]; point contacts with friction ``mu``, c1 on the block's
    face (normal out of the block), c2 the fingertip."""
    model = pin.Model()
    half = PINCH_BLOCK / 2
    block = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "block")
    model.appendBodyToJoint(block, pin.Inertia.FromBox(mass, *(PINCH_BLOCK,) * 3), pin.SE3.Identity())
    contacts, tau = [], np.zeros(8)
    for name, side in (("left", -1.0), ("right", 1.0)):
        face = np.array([side * half, 0.0, 0.0])
        finger = model.addJoint(0, pin.JointModelPX(), pin.SE3(np.eye(3), face), f"finger_{name}")
        model.appendBodyToJoint(finger, pin.Inertia.FromSphere(PINCH_FINGER_MASS, 0.005), pin.SE3.Identity())
        normal, first, second = contact_basis(np.array([side, 0.0, 0.0]))
        c1 = pin.SE3(np.column_stack([first, second, normal]), face)
        link = pin.PointContactConstraintModel(model, block, c1, finger, pin.SE3.Identity())
        link.setFriction(mu)
        contacts.append(PeerContact(name, link, PLANE_ORDER, PLANE_ORDER.T))
        tau[model.joints[finger].idx_v] = -side * squeeze
    q0 = pin.neutral(model)
    return ContactProblem(model, contacts, np.zeros(2), tau, q0, np.zeros(model.nv))


class FreeBodies:
    """Semi-implicit Euler of the model's free flyers on R^3 x SO(3): each body's linear velocity is
    stepped as a world vector (as MuJoCo does), the other coordinates as ``pin.integrate`` does.

    Pinocchio's free-flyer velocity is in the body's axes, where the linear part turns as the body turns
    (the term m w x v of h); an explicit step of that turning lengthens v by (w dt)^2 / 2 a step (2 % on
    sphere-spin over 0.25 s at 1 ms) and ``pin.integrate``'s screw motion sinks a sliding, spinning ball by
    w v dt^2 / 2 a step. Here the term is left out of the step (:meth:`turning` is added to tau), the
    centre moves by its world velocity, and the new linear velocity is carried to the new body axes.

    Raises:
        PinstabError: a free flyer whose centre of mass is not at its origin (the term is m w x v there).
    """

    def __init__(self, model: pin.Model) -> None:
        self.model = model
        self.joints = [j for j in model.joints if j.shortname() == "JointModelFreeFlyer"]
        self.masses = []
        for joint in self.joints:
            inertia = model.inertias[joint.id]
            if np.linalg.norm(inertia.lever) > 1e-12:
                raise PinstabError(
                    f"ADMM contact loop: free flyer {model.names[joint.id]!r} has its centre of mass off its origin"
                )
            self.masses.append(inertia.mass)

    def turning(self, v: np.ndarray) -> np.ndarray:
        """The linear rows' m w x v of h [N] (0 elsewhere), to add to tau."""
        term = np.zeros(self.model.nv)
        for joint, mass in zip(self.joints, self.masses, strict=True):
            linear, angular = v[joint.idx_v : joint.idx_v + 3], v[joint.idx_v + 3 : joint.idx_v + 6]
            term[joint.idx_v : joint.idx_v + 3] = mass * np.cross(angular, linear)
        return term

    def integrate(self, q: np.ndarray, v: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(q (+) dt v with the centres moved by R v_lin dt, v with the linear parts in the new axes)."""
        q_next, v_next = pin.integrate(self.model, q, dt * v), v.copy()
        for joint in self.joints:
            position, velocity = slice(joint.idx_q, joint.idx_q + 3), slice(joint.idx_v, joint.idx_v + 3)
            before = pin.Quaternion(q[joint.idx_q + 3 : joint.idx_q + 7]).toRotationMatrix()
            after = pin.Quaternion(q_next[joint.idx_q + 3 : joint.idx_q + 7]).toRotationMatrix()
            world = before @ v[velocity]
            q_next[position] = q[position] + dt * world
            v_next[velocity] = after.T @ world
        return q_next, v_next


def contact_step(
    peer: AdmmContactPeer, problem: ContactProblem, settings: SteppingSettings, statistics: SolveStatistics
):
    """``step(q, v) -> (q, v, impulses / dt)`` of the loop (module docstring); forces [N] in pinstab's
    convention, 0 for the contacts not in the step."""
    dt = settings.dt
    bodies = FreeBodies(peer.model)
    rows: dict[tuple[int, ...], np.ndarray] = {}

    def step(q: np.ndarray, v: np.ndarray):
        terms = peer.terms(q, v)
        mass_inverse_jt, acceleration = mass_solves(terms, problem.tau + bodies.turning(v))
        free = v + dt * acceleration
        gap, approach = terms.position[2::3], terms.velocity[2::3]
        active = tuple(int(i) for i in np.flatnonzero(gap + settings.theta * dt * approach <= settings.margin))
        if not active:
            return (*bodies.integrate(q, free, dt), np.zeros(peer.size))
        if active not in rows:
            rows[active] = np.concatenate([np.arange(3 * i, 3 * i + 3) for i in active])
        selected, index = rows[active], list(active)
        jacobian = terms.jacobian[selected]
        g = jacobian @ free
        bounce = problem.restitution[index] * np.minimum(approach[index], 0.0)
        g[2::3] += np.minimum(bounce, (settings.erp / dt) * np.minimum(gap[index], 0.0))
        solution = statistics.add(peer.active_impulses(active, mass_inverse_jt[:, selected], jacobian, g))
        v_next = free + solution.motion
        return (*bodies.integrate(q, v_next, dt), solution.forces / dt)

    return step


def run_contacts(
    problem: ContactProblem, settings: SteppingSettings, duration: float, record_every: int = 1
) -> PeerRun:
    """Step ``problem`` for ``duration`` [s] (the last ``record_every``-th states kept, with the forces [N]
    of their steps); CPU seconds of the loop alone."""
    peer = AdmmContactPeer.from_contacts(problem.model, problem.contacts, settings.tolerance, warm_start=True)
    statistics = SolveStatistics()
    step = contact_step(peer, problem, settings, statistics)
    return run_loop(step, problem.q0, problem.v0, settings.dt, duration, record_every, peer.size, statistics)
