"""Two round shapes touching: a sphere (shape A) against a sphere or a capsule (shape B).

Each is a *core* (a sphere's centre, a capsule's segment between its end centres) swollen by its radius. The two
touch where A's centre comes within the sum of the radii of B's core: the gap is ``|x - c| - r_a - r_b`` (x: A's
centre, c: the point of B's core nearest to x), the normal ``n = (x - c) / |x - c|`` is along the line from c to x
(into A), and the contact point is ``x - r_a n``. As x moves the point and plane move with it over both surfaces:
the contact follows the curved surfaces, re-computed at every state, not a plane frozen where it was first found.
"""

from __future__ import annotations

import numpy as np


def core_nearest(point: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The point [m] of the segment ``ends`` (2, 3) [m] (equal ends: a sphere's centre) nearest to ``point`` [m], and
    the projector (3, 3) [-] of the distance's curvature there: the identity at an end (the distance to a point),
    ``I - u u^T`` inside the segment (u its unit axis: the distance to a line does not change along it). The gap's
    Hessian in the point is ``(P - n n^T) / |point - nearest|`` (P the projector, n the unit normal)."""
    axis = ends[1] - ends[0]
    length2 = float(axis @ axis)
    along = 0.0 if length2 == 0.0 else float((point - ends[0]) @ axis) / length2
    if 0.0 < along < 1.0:
        unit = axis / np.sqrt(length2)
        return ends[0] + along * axis, np.eye(3) - np.outer(unit, unit)
    return ends[0] + min(max(along, 0.0), 1.0) * axis, np.eye(3)
