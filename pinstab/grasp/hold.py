"""``grasp-hold``: joint torques that hold a grasped object where the scene starts it.

Per state, with the contact rows ``A = [A_hand, A_object]`` of the grasp's contacts (multipliers: the
fingers' forces on the object in the contact frames):

* the contact forces ``lambda*`` that carry the object's weight (``A_object^T lambda* = g_object``) closest
  to pressing every contact with ``squeeze`` [N] along its normal, with every force inside its friction
  cone (and torsion limit) narrowed by :data:`~pinstab.grasp.holding.HOLD_MARGIN` (relative: no held contact
  sits on its cone's edge, where rounding would decide whether it slips) and every normal force at most
  ``max_squeeze`` [N] (default: no cap): the
  least-squares forces when they are inside, else a ProxQP on the cones' inscribed pyramids (``facets``
  sides), else a conic program on the exact round cones (Clarabel, :mod:`pinstab.grasp.holding`), else,
  where the load is barely held and that solve stops short of its tolerance, the forces of least squeeze
  (when within the cap). When no forces inside the cones carry the weight (a grasp without force closure,
  or the cap), the hold lets go (an event of an event-driven run, located to 1e-12 s): the least-squares
  forces are kept (with the cap: those closest to the squeeze within the cap; none with ``release``
  ``relax``), and the run names every contact that leaves its cone;
* the joint torques that make those forces an equilibrium of the hand:
  ``tau = g_hand - A_hand^T lambda* - K (theta - theta_0) - D theta_dot`` (gravity compensated, joint
  stiffness ``K`` [N m/rad] about the start and damping ``D`` [N m s/rad]).

At rest at the start this is an exact equilibrium (the object does not move); a disturbance (an
external force on the object) moves the grasp to a new one through the stiffness. It is a hold, not
an object-level controller.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pinocchio as pin

from ..contact.cones import MAX_CONE_FACETS
from ..errors import SceneError, choices
from ..forces.base import FORCE_KINDS, ForceElement
from ..kernels import hold_torques
from ..kinematics import Kinematics
from ..tables import SceneTables
from ..units import within_ceiling
from .holding import (
    FEASIBILITY,
    HOLD_MARGIN,
    UNBOUNDED,
    ConeTest,
    WarmQP,
    closest_holding,
    cone_arrays,
    cone_columns,
    least_squeeze,
    narrowed,
    pyramid_rows,
)
from .linalg import NORMAL_EQUATIONS_CONDITION, RANK_TOLERANCE, closest_solution

HOLD_VALUES = (("squeeze", "force", "N"), ("stiffness", None, "N m/rad"), ("damping", None, "N m s/rad"))
HOLD_KEYS = {
    "name",
    "kind",
    "object",
    "contacts",
    "squeeze",
    "max_squeeze",
    "facets",
    "stiffness",
    "damping",
    "release",
}
RELEASES = ("press", "relax")  # once let go: press at the cap as before, or press no more


class GraspHold(ForceElement):
    """Hold torques on the hand joints for the contacts ``contacts`` on one object.

    Args:
        name: element name. model: the scene model. contacts: the grasp contact blocks (objects with
            ``velocity_terms``, ``rows``, ``components``). object_columns: the object's velocity indices.
        squeeze: normal force per contact [N]. stiffness: [N m/rad]. damping: [N m s/rad].
        q_start: the configuration the stiffness pulls the hand joints back to.
        max_squeeze: the largest normal force of a contact [N] (inf: none). facets: sides of the pyramids
            of the fast QP. object_name: the held object (for reports). release: once it has let go
            (:attr:`released`), ``press``: the forces closest to the squeeze within the cap (the hand keeps pressing),
            or ``relax``: no contact forces (the hand keeps its gravity compensation, stiffness and damping only: the
            object is left to fall out of it).
    """

    switches = True  # its let-go, located by an event-driven run

    def __init__(
        self,
        name: str,
        model: pin.Model,
        contacts: list[Any],
        object_columns: np.ndarray,
        squeeze: float,
        stiffness: float,
        damping: float,
        q_start: np.ndarray,
        max_squeeze: float = math.inf,
        facets: int = 16,
        object_name: str = "",
        release: str = "press",
    ) -> None:
        self.name, self.kind, self.model, self.contacts = name, "grasp-hold", model, contacts
        self.object_name, self.max_squeeze, self.release = object_name, max_squeeze, release
        self.object_columns = object_columns
        self.hand_columns = hand_columns(model.nv, object_columns)
        self._object = as_slice(object_columns)  # a view where contiguous
        self._hand_int = np.asarray(self.hand_columns, dtype=np.int32)  # for the compiled balance (add_hold_balance)
        self.squeeze, self.stiffness, self.damping = squeeze, stiffness, damping
        self.q_start = q_start.copy()
        self.pressing = np.concatenate([(c.components == 2).astype(float) * squeeze for c in contacts])
        self._limits = narrowed(contacts, HOLD_MARGIN)  # the cones it holds its forces in
        columns, count = cone_columns(self._limits)
        self._normals = [c.normal for c in columns]
        caps = np.zeros((len(columns), count))
        caps[np.arange(len(columns)), self._normals] = 1.0
        self._cones = np.vstack([pyramid_rows(columns, count, facets), caps])
        limit = UNBOUNDED if math.isinf(max_squeeze) else max_squeeze
        self._lower = np.concatenate([np.zeros(len(self._cones) - len(caps)), np.full(len(caps), -UNBOUNDED)])
        self._upper = np.concatenate([np.full(len(self._cones) - len(caps), UNBOUNDED), np.full(len(caps), limit)])
        self._cone_test = ConeTest(self._limits, max_squeeze)
        self.restart()

    def held_forces(self, rows: np.ndarray, gravity: np.ndarray, t: float | None = None) -> np.ndarray:
        """The held contact forces lambda* (s,) [N, N m] given the contact rows A (s x nv) and the generalized
        gravity g(q) [N, N m] (see the module docstring); where no forces inside the cones hold, the let-go ones. With
        the time t [s] of a run, the hold lets go for good: from :attr:`released` on its forces are the let-go ones,
        without the QPs (near that bound whether a solve finds forces within its tolerance flickers, over 1e-5 s of
        allegro-tilt, and with it the hand's torques, by 0.06 N at the fingertips). An event-driven run locates the
        let-go as an event (:meth:`switch_value`, :meth:`switch`: the hold lets go at the located time, whatever the
        rejected steps tried beyond it); other runs let go at the first evaluation that finds no holding forces."""
        carrier = rows[:, self._object].T  # A_object^T: contact forces -> object generalized force
        load = gravity[self._object]
        self.holding = True
        if t is not None and t >= self.released:
            return self._let_go(carrier, load)
        # least squares: the forces closest to the squeeze among those that best carry the object's weight
        free = closest_solution(carrier, load, self.pressing)
        if self._cone_test.holds(free):
            return free
        count = len(free)
        solution, solved, _ = self._pyramid_qp.solve(
            np.eye(count), -self.pressing, carrier, load, self._cones, self._lower, self._upper, screen=True
        )
        if solved and self._cone_test.holds(solution):
            return solution
        exact = closest_holding(carrier, load, self._limits, self.pressing, self.max_squeeze)
        if exact.holds:
            return exact.forces
        least = least_squeeze(carrier, load, self._limits)  # barely held, the closest solve can fail where this holds
        if least.holds and least.squeeze <= self.max_squeeze * (1.0 + FEASIBILITY):
            return least.forces
        self.holding = False
        if t is not None and not self.located:
            self.released = t
        return self._let_go(carrier, load, free)

    def _let_go(self, carrier: np.ndarray, load: np.ndarray, free: np.ndarray | None = None) -> np.ndarray:
        """The forces [N, N m] when none inside the cones hold: the least-squares ``free`` ones (None: found here), or
        with a cap those closest to the squeeze within it (the fingers press at most max_squeeze, and some contact
        leaves its cone); none with ``release`` ``relax``."""
        if self.release == "relax":
            return np.zeros(len(self.pressing))
        if free is None:
            free = closest_solution(carrier, load, self.pressing)
        if math.isinf(self.max_squeeze):
            return free
        count, caps = len(free), len(self._normals)
        capped, solved, _ = self._capped_qp.solve(
            np.eye(count), -self.pressing, carrier, load, self._cones[-caps:], self._lower[-caps:], self._upper[-caps:]
        )
        return capped if solved else free

    def restart(self) -> None:
        """A run starts: the hold holds again (:attr:`released` inf) and its QPs start cold (a warm start from an
        earlier run's last solve gave start forces 1e-11 N apart from a fresh hold's)."""
        self._pyramid_qp, self._capped_qp = WarmQP(), WarmQP()  # warm-started from the previous evaluation's
        self.released = math.inf  # [s] when the hold let go in the current run (inf: it holds)
        self.located = False  # whether the run locates the let-go (an event-driven run: :meth:`watch`)
        self.holding = True  # whether the last evaluation found holding forces (or the hold had let go before)
        self._evaluated: tuple[float, bytes] | None = None  # (t [s], q) of the last evaluation in a run

    def watch(self) -> None:
        """The run locates the let-go (:meth:`switch`): an evaluation without holding forces no longer lets go."""
        self.located = True

    def switch_value(self, q: np.ndarray, t: float) -> float | None:
        """The let-go's event function at (q, t) from the last evaluation (None: that was at another state): 1 while
        some forces inside the cones hold the object (or the hold has let go already), -1 once none do (a sign change
        that bisection locates: the holding set shrinks to nothing there, with no margin that reaches zero
        smoothly)."""
        if self._evaluated != (t, q.tobytes()):
            return None
        return 1.0 if self.holding else -1.0

    def switch(self, t: float) -> str | None:
        """Let go at the located event at t [s] when the last evaluation found no holding forces; the event's cause
        (``no forces inside the cones hold <object>``), else None."""
        if self.holding:
            return None
        self.released = t
        return f"no forces inside the cones hold {self.object_name or self.name}"

    def torques(
        self, rows: np.ndarray, gravity: np.ndarray, q: np.ndarray, v: np.ndarray, t: float | None = None
    ) -> np.ndarray:
        """The hand's joint torques tau (nv,) [N m] at (q, v) given the contact rows A (s x nv) and the
        generalized gravity g(q) [N, N m]: gravity, minus the held forces' torques (at a run's time t [s], see
        :meth:`held_forces`), stiffness and damping (the compiled balance, ``cpp/grasp_forces.cpp``, the core's hold's
        too)."""
        forces = self.held_forces(rows, gravity, t)
        deviation = pin.difference(self.model, self.q_start, q)
        return hold_torques(rows, self._hand_int, gravity, forces, deviation, v, self.stiffness, self.damping)

    def generalized_force(self, kin: Kinematics, v: np.ndarray, t: float) -> np.ndarray:
        rows = contact_rows(self.contacts, kin, 0.0)
        self._evaluated = (t, kin.q.tobytes())
        return self.torques(rows, kin.gravity(), kin.q, v, t)

    def compiled_form(self, rows: Mapping[str, slice]) -> dict[str, Any]:
        """The hold for the compiled grasp evaluation: its contacts' rows in the stack, the columns, the squeeze, the
        contacts' limits as :class:`~pinstab.grasp.holding.ConeTest` reads them (columns: normal, tangents, spin; -1:
        none; friction and torsion coefficients) and the tolerances of its least squares and cone test. (The kernel
        keeps the least-squares forces only: where they leave a limit or the cap, the evaluation is not used and this
        element's QPs take them.)"""
        columns, mu, torsion = cone_arrays(cone_columns(self._limits)[0])
        return {
            "kind": "hold",
            "rows": np.r_[tuple(rows[c.name] for c in self.contacts)].astype(np.int32),
            "object_columns": np.asarray(self.object_columns, dtype=np.int32),
            "hand_columns": np.asarray(self.hand_columns, dtype=np.int32),
            "pressing": self.pressing,
            "cone_columns": columns,
            "cone_mu": mu,
            "cone_torsion": torsion,
            "q_start": self.q_start,
            "stiffness": float(self.stiffness),
            "damping": float(self.damping),
            "cap": float(self.max_squeeze),  # inf: none
            "feasibility": FEASIBILITY,
            "rank": RANK_TOLERANCE,
            "condition": NORMAL_EQUATIONS_CONDITION,
        }


@FORCE_KINDS.register(
    "grasp-hold", summary="hand joint torques that hold a grasped object: weight, squeeze, joint stiffness and damping"
)
def parse_grasp_hold(entry: dict, tables: SceneTables, name: str, where: str) -> GraspHold:
    """Scene table: ``object``, ``contacts`` (names; default: every grasp contact on the object),
    ``squeeze`` [N] per contact, ``max_squeeze`` [N] (the largest normal force; default: no cap), ``facets``
    (sides of the fast QP's pyramids, 16), ``stiffness`` [N m/rad] and ``damping`` [N m s/rad] (default 0),
    ``release`` (:data:`RELEASES`, default ``press``: what it does once it has let go)."""
    tables.check_keys(entry, HOLD_KEYS, where)
    item, contacts, columns = grasped_contacts(entry, tables, where)
    values = {}
    for key, dimension, unit in HOLD_VALUES:
        if dimension is None:
            values[key] = tables.number(entry, key, where, default=0.0)
        else:
            values[key] = tables.quantity(entry.get(key, 0.0), dimension, f"{where}.{key}")
        if values[key] < 0:
            raise SceneError(f"{where}.{key} must be >= 0, got {entry[key]!r}")
        within_ceiling(values[key], f"{where}.{key}", unit)
    cap = tables.quantity(entry["max_squeeze"], "force", f"{where}.max_squeeze") if "max_squeeze" in entry else math.inf
    if not cap >= values["squeeze"]:
        raise SceneError(
            f"{where}.max_squeeze must be >= squeeze ({values['squeeze']:g} N), got {entry['max_squeeze']!r}"
        )
    facets = entry.get("facets", 16)
    if isinstance(facets, bool) or not isinstance(facets, int) or not 3 <= facets <= MAX_CONE_FACETS:
        raise SceneError(f"{where}.facets must be a whole number >= 3 (at most {MAX_CONE_FACETS}), got {facets!r}")
    release = entry.get("release", "press")
    if release not in RELEASES:
        raise SceneError(f"{where}.release: unknown release {release!r}; releases: {choices(RELEASES)}")
    return GraspHold(
        name,
        tables.model,
        contacts,
        columns,
        q_start=tables.q0,
        max_squeeze=cap,
        facets=facets,
        object_name=item.name,
        release=release,
        **values,
    )


def hand_columns(nv: int, object_columns: np.ndarray) -> np.ndarray:
    """The velocity indices that are not the object's: the hand's (and any other body's)."""
    hand = np.ones(nv, dtype=bool)
    hand[object_columns] = False
    return np.flatnonzero(hand)


def as_slice(indices: np.ndarray) -> slice | np.ndarray:
    """Consecutive indices as the slice that selects them (a view, cheaper than fancy indexing), else as they are."""
    if len(indices) and np.array_equal(indices, np.arange(indices[0], indices[0] + len(indices))):
        return slice(int(indices[0]), int(indices[0]) + len(indices))
    return indices


def contact_rows(contacts: list[Any], kin: Kinematics, t: float) -> np.ndarray:
    """The grasp contacts' rows stacked (s x nv) at ``kin``'s configuration and time t [s]; Jacobians current."""
    return np.vstack([c.velocity_terms(kin, kin.q, t).jacobian for c in contacts])


def grasped_object(entry: dict, tables: SceneTables, where: str) -> tuple[Any, np.ndarray]:
    """(the object ``entry['object']``, its velocity indices), checked and named in errors."""
    if not isinstance(entry.get("object"), str) or entry["object"] not in tables.objects:
        raise SceneError(
            f"{where}.object: {entry.get('object')!r} is not an object; objects: {choices(tables.objects)}"
        )
    item = tables.objects[entry["object"]]
    joint = tables.model.joints[item.joint]
    return item, np.arange(joint.idx_v, joint.idx_v + joint.nv)


def grasped_contacts(entry: dict, tables: SceneTables, where: str) -> tuple[Any, list[Any], np.ndarray]:
    """(the object ``entry['object']``, the grasp contacts ``entry['contacts']`` on it (default: all of
    them), the object's velocity indices), each checked and named in errors."""
    item, columns = grasped_object(entry, tables, where)
    grasp = {c.name: c for c in tables.constraints.values() if getattr(c, "object_name", None) == item.name}
    names = entry.get("contacts", list(grasp))
    if not isinstance(names, list) or not names:
        raise SceneError(f"{where}.contacts must name grasp contacts on {item.name!r}; contacts: {choices(grasp)}")
    for contact in names:
        if not isinstance(contact, str) or contact not in grasp:
            raise SceneError(
                f"{where}.contacts: {contact!r} is not a grasp contact on {item.name!r}; contacts: {choices(grasp)}"
            )
    return item, [grasp[c] for c in names], columns
