"""Point contacts found from collision geometry (kind ``geometry``, :mod:`pinstab.contact.geometry`).

Scene table::

    [[contacts]]
    kind = "geometry"
    pairs = [["box_0", "ground"]]   # optional; default every shape against every other but adjacent links
    mu = 0.3                        # optional (frictionless without), as plane-contact's; facets, restitution too
    ground = {normal = [0, 0, 1], point = [0, 0, 0]}   # the default; false: no ground
    margin = 0.005                  # [m] optional; features this close to a pair's nearest one count

coal finds each allowed pair's contact features at the scene's initial configuration; each is read as a
``plane-contact`` (:func:`~pinstab.constraints.contacts.parse_plane_contact`, so that its checks are that kind's)
named ``<shapeA>/<shapeB>[k]``: the point of body A (a sphere's centre with its radius) on the separating plane,
the ground's fixed in the world, another body's carried by it (event-driven contacts only).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..contact.geometry import GROUND, ContactShapes, Feature
from ..errors import SceneError
from ..tables import SceneTables
from .base import CONSTRAINT_KINDS
from .contacts import PointContact, parse_plane_contact

GEOMETRY_KEYS = {"kind", "pairs", "mu", "facets", "restitution", "ground", "margin"}
COPIED = ("mu", "facets", "restitution")  # the keys each found contact takes from the entry


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


def parse_geometry_contacts(entry: dict[str, Any], tables: SceneTables, name: str, where: str) -> list[PointContact]:
    """The point contacts coal finds at the scene's initial configuration (module docstring), in pair order."""
    tables.check_keys(entry, GEOMETRY_KEYS, where)
    shapes = contact_shapes(entry, tables, where)
    found = shapes.features(tables.q0)
    copied = {key: entry[key] for key in COPIED if key in entry}
    return [
        parse_plane_contact(
            {**copied, **_plane_entry(shapes, feature)}, tables, feature.name, f"contact {feature.name!r}"
        )
        for feature in found
    ]


def _plane_entry(shapes: ContactShapes, feature: Feature) -> dict[str, Any]:
    """A ``plane-contact`` table for a feature: its point on body A's frame, the plane on the world or on B."""
    model, objects = shapes.model, shapes.geometry.geometryObjects
    a, b = shapes.pairs[feature.pair]
    frame_a = model.frames[objects[a].parentFrame]
    entry: dict[str, Any] = {
        "frame_a": frame_a.name,
        "offset_a": frame_a.placement.actInv(feature.joint_point).tolist(),
        "normal": feature.normal.tolist(),
        "point": feature.point.tolist(),
    }
    if feature.radius:
        entry["radius"] = feature.radius
    if objects[b].parentJoint != 0:  # the plane in B's frame, carried by it
        frame_b = model.frames[objects[b].parentFrame]
        placed = shapes.frame_placement(objects[b].parentFrame)
        entry.update(
            frame_b=frame_b.name,
            normal=(placed.rotation.T @ feature.normal).tolist(),
            point=placed.actInv(feature.point).tolist(),
        )
    return entry


def _ground(entry: dict[str, Any], tables: SceneTables, where: str) -> tuple[np.ndarray, np.ndarray] | None:
    """The ground's (unit normal, point [m]) from ``ground`` (default: the plane z = 0), or None for ``false``."""
    value = entry.get("ground", True)
    if value is False:
        return None
    if value is True:
        value = {}
    if not isinstance(value, dict):
        raise SceneError(f"{where}.ground must be a table (normal, point) or false (no ground), got {value!r}")
    tables.check_keys(value, {"normal", "point"}, f"{where}.{GROUND}")
    normal = tables.direction(value.get("normal", [0.0, 0.0, 1.0]), f"{where}.ground.normal")
    point = tables.vector(value.get("point", [0.0, 0.0, 0.0]), 3, f"{where}.ground.point", "length")
    tables.within_reach(point, f"{where}.ground.point", True)
    return normal, point


CONSTRAINT_KINDS.register(
    "geometry",
    parse_geometry_contacts,
    summary="point contacts found by coal from the collision shapes (robot, objects, ground): one per feature",
)
