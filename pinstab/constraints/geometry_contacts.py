"""Point contacts found from collision geometry (kind ``geometry``, :mod:`pinstab.contact.geometry`).

Scene table::

    [[contacts]]
    kind = "geometry"
    pairs = [["box_0", "ground"]]   # optional; default every shape against every other but adjacent links
    mu = 0.3                        # optional (frictionless without), as plane-contact's; facets, restitution too
    rolling = "3 mm"                # optional, as plane-contact's (event-driven contacts); torsion too
    ground = {normal = [0, 0, 1], point = [0, 0, 0]}   # the default; false: no ground; a list: several planes
    margin = 0.005                  # [m] optional; features this close to a pair's nearest one count

coal finds each allowed pair's contact features (:class:`FoundContacts`); each is a
:class:`~pinstab.constraints.contacts.PointContact` named ``<shapeA>/<shapeB>[k]`` (with plane-contact's
coefficients and start check): the point of body A (a sphere's centre with its radius) on the separating plane
where it was found, the ground's fixed in the world, another body's carried by it (event-driven and time-stepping
contacts only). The scene's constraints are those found at its initial configuration; an event-driven run finds
them again after every step (:class:`~pinstab.integration.events.EventLoop`), a time-stepping run before every
step (:class:`~pinstab.integration.contact_stepping.ContactStepper`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ..contact.cones import FrictionCone
from ..contact.geometry import GROUND, ContactShapes, Feature
from ..errors import SceneError
from ..tables import SceneTables
from .base import CONSTRAINT_KINDS
from .contacts import PointContact, check_penetration, contact_coefficients, rotational_friction

GEOMETRY_KEYS = {"kind", "pairs", "mu", "facets", "restitution", "ground", "margin", "torsion", "rolling"}


def contact_shapes(entry: dict[str, Any], tables: SceneTables, where: str) -> ContactShapes:
    """The scene's collision shapes (the robot's, the objects', the ground) with the entry's pairs allowed."""
    shapes = ContactShapes(
        tables.model, tables.robot_shapes(), list(tables.objects.values()), _ground(entry, tables, where)
    )
    margin = None
    if "margin" in entry:
        margin = tables.quantity(entry["margin"], "length", f"{where}.margin")
        if not margin >= 0.0:
            raise SceneError(f"{where}.margin must be a length >= 0 [m], got {entry['margin']!r}")
        tables.within_reach(margin, f"{where}.margin")
    if "pairs" not in entry:
        pairs = shapes.default_pairs()
    else:
        value = entry["pairs"]
        if not isinstance(value, list) or not all(isinstance(p, list) and len(p) == 2 for p in value):
            raise SceneError(f"{where}.pairs must be a list of [shape, shape] name pairs, got {value!r}")
        pairs = [tuple(shapes.shape(n, f"{where}.pairs[{k}]") for n in pair) for k, pair in enumerate(value)]
    if not pairs:
        raise SceneError(f"{where}: no pair of collision shapes may touch; shapes: {', '.join(shapes.names)}")
    for k, (a, b) in enumerate(pairs):
        shapes.allow(a, b, margin, f"{where}.pairs[{k}]")
    return shapes


class FoundContacts:
    """The point contacts coal finds from a scene's collision shapes (:class:`~pinstab.contact.geometry.ContactShapes`),
    each the same :class:`~pinstab.constraints.contacts.PointContact` while it persists.

    Args:
        shapes: the shapes with their pairs allowed; an operational frame is added to its model at every feature
            point of every pair (named like its contact). friction: the contacts' cone (None: frictionless).
        restitution: their Newton's e [-]. spin: their (torsion, rolling) [m].

    Attributes:
        order: each contact found so far, by name: its place in a run's order, (pair, point index).
    """

    def __init__(
        self,
        shapes: ContactShapes,
        friction: FrictionCone | None,
        restitution: float,
        spin: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        self.shapes, self.friction, self.restitution, self.spin = shapes, friction, restitution, spin
        model, objects = shapes.model, shapes.geometry.geometryObjects
        self.frames: dict[tuple[int, int], int] = {}  # (pair, point index) -> the frame at the point on body A
        for pair, (a, _) in enumerate(shapes.pairs):
            shape = objects[a]
            for k, point in enumerate(shapes.joint_points(pair).T):
                frame = pin.Frame(
                    f"{shapes.label(pair)}[{k}]",
                    shape.parentJoint,
                    shape.parentFrame,
                    pin.SE3(np.eye(3), point),
                    pin.FrameType.OP_FRAME,
                )
                self.frames[pair, k] = model.addFrame(frame)
        self.order: dict[str, tuple[int, int]] = {}
        self._made: dict[str, PointContact] = {}
        self._last: tuple[tuple, list[PointContact]] = ((), [])  # the last find's key and contacts

    def contacts(self, q: np.ndarray, start: np.ndarray | None = None) -> list[PointContact]:
        """The contacts found at configuration q, in pair order, then by point (a contact found before: the same
        object, its plane where it was first found). ``start``: the configuration a new contact's plane is taken
        at (default q): an event-driven step's start, where the contact is still apart, not its end, which may be
        deep inside (a box falling through the stack in a trial step of 0.14 s: its corners on the wrong faces)."""
        located = self.shapes.find(q)
        key = located.key()
        if key == self._last[0]:  # the features found last (all made then): their contacts, without their tuples
            return list(self._last[1])
        found = self.shapes.features_of(located)
        new = {feature.pair for feature in found if feature.name not in self._made}
        if start is not None:
            for pair in sorted(new):
                for feature in self.shapes.pair_features(start, pair):
                    if feature.name in {f.name for f in found}:
                        self._contact(feature)
        contacts = [self._contact(feature) for feature in found]
        self._last = key, contacts
        return list(contacts)

    def _contact(self, feature: Feature) -> PointContact:
        contact = self._made.get(feature.name)
        if contact is not None:
            return contact
        shapes = self.shapes
        shape_b = shapes.geometry.geometryObjects[shapes.pairs[feature.pair][1]]
        frame = self.frames[feature.pair, feature.index]
        centre_gap = float(feature.normal @ (feature.world - feature.point))
        anchor, normal, plane_frame = feature.world - feature.normal * centre_gap, feature.normal, None
        core = shapes.cores[feature.pair]
        if shape_b.parentJoint != 0 or core is not None:  # the plane in B's frame, carried by it
            plane_frame = shape_b.parentFrame
            placed = shapes.frame_placement(plane_frame)
            anchor, normal = placed.actInv(anchor), placed.rotation.T @ normal
        arguments = (
            feature.name,
            frame,
            anchor,
            normal,
            self.friction,
            self.restitution,
            feature.radius,
            plane_frame,
            *self.spin,
        )
        if core is None:
            contact = PointContact(*arguments)
        else:  # a round pair: B's core in the plane's frame, the plane re-computed at every state
            ends = np.array([placed.actInv(end) for end in shapes.core_world(feature.pair)])
            contact = RoundContact(*arguments, core=ends, core_radius=float(shape_b.geometry.radius))
        self._made[feature.name] = contact
        self.order[feature.name] = (feature.pair, feature.index)
        return contact


class RoundContact(PointContact):
    """A sphere's contact with a sphere or a capsule (:mod:`~pinstab.contact.round_pairs`): a
    :class:`~pinstab.constraints.contacts.PointContact` whose plane (``anchor``, ``normal``: where it was found) the
    event-driven and time-stepping dynamics re-compute at every state from the line of centres; held rows do not
    take it (its plane turns as the sphere moves).

    Args:
        core: B's core ends (2, 3) [m, in ``plane_frame``'s axes, B's operational frame, 0 for the world].
        core_radius: B's radius [m]. The others: as :class:`PointContact`'s (``radius``: the sphere's).
    """

    def __init__(self, *arguments: Any, core: np.ndarray, core_radius: float) -> None:
        super().__init__(*arguments)
        self.core, self.core_radius = core, core_radius


def parse_geometry_contacts(entry: dict[str, Any], tables: SceneTables, name: str, where: str) -> list[PointContact]:
    """The point contacts coal finds at the scene's initial configuration (module docstring), in pair order; the
    finder is added to the scene's (``tables.contact_finders``), which event-driven runs ask again at every step.

    Raises:
        SceneError: a contact starting deeper inside its plane than plane-contact allows (naming it).
    """
    tables.check_keys(entry, GEOMETRY_KEYS, where)
    friction, restitution = contact_coefficients(entry, where)
    spin = rotational_friction(entry, tables, friction, where)
    finder = FoundContacts(contact_shapes(entry, tables, where), friction, restitution, spin)
    tables.contact_finders.append(finder)
    for feature in finder.shapes.features(tables.q0):
        check_penetration(feature.gap, tables.size, f"contact {feature.name!r}")
    return finder.contacts(tables.q0)


def _ground(entry: dict[str, Any], tables: SceneTables, where: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """The ground planes' (unit normal, point [m]) from ``ground``: a table (``normal``, ``point``; default the plane
    z = 0), a list of them (half-spaces named ``ground``, ``ground_1``, ...), or ``false`` (none)."""
    value = entry.get("ground", True)
    if value is False:
        return []
    if value is True:
        value = {}
    planes = value if isinstance(value, list) and value else [value]
    grounds = []
    for k, plane in enumerate(planes):
        at = f"{where}.{GROUND}" if len(planes) == 1 else f"{where}.{GROUND}[{k}]"
        if not isinstance(plane, dict):
            raise SceneError(
                f"{at} must be a table (normal, point), a list of them or false (no ground), got {plane!r}"
            )
        tables.check_keys(plane, {"normal", "point"}, at)
        normal = tables.direction(plane.get("normal", [0.0, 0.0, 1.0]), f"{at}.normal")
        point = tables.vector(plane.get("point", [0.0, 0.0, 0.0]), 3, f"{at}.point", "length")
        tables.within_reach(point, f"{at}.point", True)
        grounds.append((normal, point))
    return grounds


CONSTRAINT_KINDS.register(
    "geometry",
    parse_geometry_contacts,
    summary="point contacts found by coal from the collision shapes (robot, objects, ground): one per feature",
)
