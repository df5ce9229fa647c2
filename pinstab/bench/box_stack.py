"""The contacts of ``box-stack``'s cubes declared one by one (``plane-contact``; a cube's top corners on the face of
the cube above, carried by it): what contacts found from geometry are compared with, by
``tests/test_geometry_stacks.py`` and ``benchmarks/geometry_contacts.py``."""

from __future__ import annotations

from typing import Any

from pinstab.generators import BOX_SIDE

HALF = BOX_SIDE / 2  # [m]
BOTTOM_CORNERS = (1, 3, 5, 7)  # a cube's corners (shape_points' order, signs (x, y, z) from +++) with z = -half
TOP_CORNERS = (0, 2, 4, 6)  # ... with z = +half


def corner(k: int) -> list[float]:
    """Cube corner k's offset [m] from its centre, in :func:`~pinstab.contact.geometry.shape_points`' order."""
    signs = [(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)][k]
    return [s * HALF for s in signs]


def declared_stack(names: list[str], mu: float) -> tuple[list[dict[str, Any]], dict[str, str]]:
    """The contacts of the cubes ``names`` (objects, bottom up) declared with friction ``mu``: every cube's bottom
    corners on the ground, every cube's top corners on the bottom face of the cube above; and the declared name of
    each contact found from geometry (``<cube>/collision0/ground[k]``, ``<cube>/collision0/<above>/collision0[k]``)."""
    entries: list[dict[str, Any]] = []
    names_found: dict[str, str] = {}
    for j, name in enumerate(names):
        for k in BOTTOM_CORNERS:
            entries.append(
                {"name": f"{name}-ground{k}", "kind": "plane-contact", "frame_a": name, "offset_a": corner(k), "mu": mu}
            )
            names_found[f"{name}/collision0/ground[{k}]"] = entries[-1]["name"]
        if j + 1 == len(names):
            continue
        above = names[j + 1]
        for k in TOP_CORNERS:
            entries.append(
                {
                    "name": f"{name}-{above}{k}",
                    "kind": "plane-contact",
                    "frame_a": name,
                    "offset_a": corner(k),
                    "frame_b": above,
                    "normal": [0.0, 0.0, -1.0],
                    "point": [0.0, 0.0, -HALF],
                    "mu": mu,
                }
            )
            names_found[f"{name}/collision0/{above}/collision0[{k}]"] = entries[-1]["name"]
    return entries, names_found
