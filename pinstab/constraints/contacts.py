"""Point contacts of a body point with a fixed world plane (the ground, a table top).

Kind ``plane-contact``: a point on body a touching the plane ``{x : n . (x - p0) = 0}``. Without
``mu`` the contact is frictionless: one ``unilateral`` row, the gap ``n . (p_a - p0) >= 0``, whose
multiplier (the normal force [N]) can only push. With ``mu`` it is a sticking contact with Coulomb
friction: three ``cone`` rows in the contact frame (normal, then two tangents) that hold the point at
its anchor, the force kept inside ``|f_t| <= mu f_n``. The anchor is the point's projection on the
plane at the scene's declared initial configuration. Contacts that open, close or slide over a run are
not modelled here. With ``radius`` r the point is a sphere's centre and its touching point, ``p_a - r n``, is
the contact point (one rule for every treatment: held rows hold the centre at r above the anchor, event-driven
and time-stepping contacts take the touching point's gap and velocity, pinstab/solvers/contact_modes.py).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..contact.coefficients import MAX_FRICTION, friction_coefficient, restitution_coefficient
from ..contact.cones import FrictionCone
from ..errors import ConstraintError, SceneError
from ..kinematics import Kinematics
from ..tables import SceneTables, unit
from .base import CONSTRAINT_KINDS, RowKind
from .loops import FrameClosure, plane_basis

CONTACT_KEYS = {
    "name",
    "kind",
    "frame_a",
    "offset_a",
    "rpy_a",
    "frame_b",
    "offset_b",
    "rpy_b",
    "normal",
    "point",
    "mu",
    "facets",
    "restitution",
    "radius",
    "torsion",
    "rolling",
}
MAX_PENETRATION = 1e-4  # [-] scene sizes: the deepest a contact point may start inside its plane. Declared starts
# are rounded (unit quaternions to 4 digits leave a 0.1 m arm 1e-5 m off); deeper, the start is a mistake: a rigid
# contact cannot start inside its plane (event-driven contacts keep the depth, time-stepping ones pop the body
# out at depth / dt)


def contact_basis(normal: np.ndarray) -> np.ndarray:
    """Rows (n, t1, t2): the unit normal and the plane's two tangents, t1 x t2 = n."""
    return np.vstack([unit(normal), plane_basis(normal)])


class PointContact(FrameClosure):
    """A body point on a world plane: 1 unilateral row (frictionless) or 3 cone rows (friction).

    Args:
        name: unique name. frame_a: the operational frame at the contact point of body a.
        anchor: the world point [m] the contact holds (on the plane).
        normal: the plane's normal (world axes; into body a, i.e. the direction it is pushed).
        friction: the Coulomb cone, or None for a frictionless contact.
        restitution: Newton's coefficient e [-] of its impacts (event-driven contacts).
        radius: a sphere of this radius [m] centred at the point touches the plane (its gap is the centre's
            height minus the radius; held rows hold the centre at ``anchor + radius * normal``); 0: the point
            itself (a vertex).
        plane_frame: for event-driven contacts, the operational frame of body b carrying the plane (None: the
            plane is fixed in the world); ``anchor`` and ``normal`` are then in its axes.
        torsion, rolling: the rotational friction [m] of event-driven contacts: the largest torque about the
            normal, about the tangents, per unit normal force (:func:`rotational_friction`).

    The multipliers are the contact force on body a [N] in the contact frame (normal, t1, t2).

    Attributes:
        core, core_radius: a round pair's B core and radius
            (:class:`~pinstab.constraints.geometry_contacts.RoundContact`); None and 0 for a plane.
    """

    core: np.ndarray | None = None
    core_radius: float = 0.0

    def __init__(
        self,
        name: str,
        frame_a: int,
        anchor: np.ndarray,
        normal: np.ndarray,
        friction: FrictionCone | None,
        restitution: float = 0.0,
        radius: float = 0.0,
        plane_frame: int | None = None,
        torsion: float = 0.0,
        rolling: float = 0.0,
    ) -> None:
        basis = contact_basis(normal)
        anchor = np.asarray(anchor, dtype=float)
        super().__init__(name, "point", frame_a, None, pin.SE3(np.eye(3), anchor + radius * basis[0]))
        self.kind = "contact"
        self.friction = friction
        self.row_kind = RowKind.UNILATERAL if friction is None else RowKind.CONE
        self.selection = basis[:1] if friction is None else basis
        self.rows = self.selection.shape[0]
        self.force_frame = "contact frame (normal, t1, t2), force on a"
        self.restitution = restitution
        self.radius = radius
        self.plane_frame = plane_frame
        self.plane_point = anchor.copy()  # [m] on the plane (the held centre's foot)
        self.torsion, self.rolling = torsion, rolling

    def slip(self, kin: Kinematics) -> float | None:
        """A sticking contact's distance from its anchor [m]; None when frictionless (it may slide)."""
        if self.friction is None:
            return None
        return float(np.linalg.norm(kin.placement(self.frame_a).translation - self.world_placement_b.translation))


def parse_plane_contact(entry: dict, tables: SceneTables, name: str, where: str) -> PointContact:
    """Scene table: ``frame_a`` + ``offset_a`` [m], ``normal`` (default +z), ``point`` on the plane
    [m] (default the origin), ``mu`` (omit for frictionless), ``facets`` of the linearized cone, ``restitution``
    e in [0, 1] of its impacts (event-driven contacts; default 0), ``radius`` [m] of a sphere at the point.
    With ``frame_b`` (+ ``offset_b``, ``rpy_b``) the plane is carried by that body: ``normal`` and ``point``
    are in the frame's axes (event-driven contacts only). ``torsion`` and ``rolling`` [m]: rotational friction
    (event-driven contacts; :func:`rotational_friction`)."""
    tables.check_keys(entry, CONTACT_KEYS, where)
    frame = tables.attached_frame(entry, "frame_a", "offset_a", "rpy_a", f"{name}/a", where)
    plane_frame = None
    if "frame_b" in entry:
        plane_frame = tables.attached_frame(entry, "frame_b", "offset_b", "rpy_b", f"{name}/b", where)
    elif "offset_b" in entry or "rpy_b" in entry:
        raise SceneError(f"{where}: 'offset_b' and 'rpy_b' place the plane on body 'frame_b'; give 'frame_b' too")
    normal = tables.direction(entry.get("normal", [0.0, 0.0, 1.0]), f"{where}.normal")
    point = tables.vector(entry.get("point", [0.0, 0.0, 0.0]), 3, f"{where}.point", "length")
    tables.within_reach(point, f"{where}.point", plane_frame is None)  # a world plane: from the bodies
    friction, restitution = contact_coefficients(entry, where)
    torsion, rolling = rotational_friction(entry, tables, friction, where)
    radius = tables.number(entry, "radius", where, 0.0)
    if radius < 0.0:
        raise SceneError(f"{where}.radius must be >= 0 [m], got {radius!r}")
    tables.within_reach(radius, f"{where}.radius")
    if radius and plane_frame is not None:
        raise SceneError(f"{where}: 'radius' takes a plane fixed in the world; a plane on 'frame_b' touches a point")
    plane = pin.SE3.Identity() if plane_frame is None else tables.initial_placement(plane_frame)
    start = plane.actInv(tables.initial_placement(frame).translation)
    gap = float(normal @ (start - point))
    check_penetration(gap - radius, tables.size, where)
    return PointContact(
        name, frame, start - normal * gap, normal, friction, restitution, radius, plane_frame, torsion, rolling
    )


def contact_coefficients(entry: dict, where: str) -> tuple[FrictionCone | None, float]:
    """A contact table's friction cone (``mu``, ``facets``; None without ``mu``: frictionless) and Newton's
    restitution e [-] (``restitution``, default 0)."""
    friction = None
    if "mu" in entry:
        try:
            friction = FrictionCone(friction_coefficient(entry["mu"], f"{where}.mu"), entry.get("facets", 8))
        except ConstraintError as exc:
            raise SceneError(f"{where}: {exc}") from None
    elif "facets" in entry:
        raise SceneError(f"{where}: 'facets' linearizes a friction cone; give 'mu' too")
    return friction, restitution_coefficient(entry.get("restitution", 0.0), f"{where}.restitution")


def friction_length(entry: dict, key: str, tables: SceneTables, where: str) -> float:
    """A rotational friction's length [m] ``entry[key]`` (a number or ``"3 mm"``; 0 when absent): the largest torque
    per unit normal force, >= 0 and within the scene's reach (:meth:`~pinstab.tables.SceneTables.within_reach`).

    Raises:
        SceneError: naming ``where.key``, the value and the valid range.
    """
    if key not in entry:
        return 0.0
    value = tables.quantity(entry[key], "length", f"{where}.{key}")
    if not value >= 0.0:
        raise SceneError(
            f"{where}.{key} must be a length >= 0 [m] (the largest torque per unit normal force), got {entry[key]!r}"
        )
    tables.within_reach(value, f"{where}.{key}")
    return value


def rotational_friction(
    entry: dict, tables: SceneTables, friction: FrictionCone | None, where: str
) -> tuple[float, float]:
    """A contact table's rotational friction (``torsion``, ``rolling``) [m], 0 when absent: event-driven contacts
    bound the torque about the normal by ``torsion f_n`` and about the tangents by ``rolling f_n`` (MuJoCo's
    condim 6), each holding its relative angular velocity at zero below its bound, opposing it at its bound.

    Raises:
        SceneError: a negative or non-numeric value, or one on a contact without friction (``mu``).
    """
    torsion, rolling = (friction_length(entry, key, tables, where) for key in ("torsion", "rolling"))
    if (torsion or rolling) and friction is None:
        key = "torsion" if torsion else "rolling"
        raise SceneError(
            f"{where}.{key}: rotational friction acts on a contact with friction; give 'mu' too (a number in "
            f"[0, {MAX_FRICTION:g}]) or drop '{key}'"
        )
    return torsion, rolling


def check_penetration(gap: float, size: float, where: str) -> None:
    """Refuse a contact starting deeper than :data:`MAX_PENETRATION` scene sizes (``size`` [m]) inside its plane
    (``gap`` [m] < 0: inside)."""
    if gap < -MAX_PENETRATION * size:
        raise SceneError(
            f"{where}: the contact point starts {-gap:.6g} m inside its plane, deeper than {MAX_PENETRATION:g} times "
            f"the scene's size ({size:.3g} m), the allowed depth [0, {MAX_PENETRATION * size:.3g}] m: a rigid "
            "contact cannot start inside its plane; check the offset, the plane's point and normal, and initial.q"
        )


CONSTRAINT_KINDS.register(
    "plane-contact",
    parse_plane_contact,
    summary="a body point on a world plane: frictionless (1 unilateral row) or sticking with friction mu (3 cone rows)",
)
