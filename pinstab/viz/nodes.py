"""Placing and colouring meshcat nodes the same way in a live viewer and in a recorded animation frame.

A live viewer takes a full 4 x 4 matrix and a ``color`` property that reaches every mesh below the node;
an animation frame keeps position and rotation tracks only, so scale and colour become tracks of their
own, the colour on the mesh itself (the ``<object>`` child, where three.js finds a material).
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from meshcat.animation import AnimationFrameVisualizer

ROOT = "pinstab"
Y_AXIS = np.array([0.0, 1.0, 0.0])


def set_pose(node, placement: pin.SE3, scale: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> None:
    """Place ``node`` (viewer or animation-frame node) at ``placement`` [m], scaled along its own axes."""
    if isinstance(node, AnimationFrameVisualizer):
        node.set_transform(placement.homogeneous)
        node.set_property("scale", "vector3", [float(s) for s in scale])
    else:
        node.set_transform(placement.homogeneous @ np.diag([*scale, 1.0]))


def set_color(node, color: tuple[float, float, float], opacity: float) -> None:
    """Colour the mesh set at ``node`` (RGB in [0, 1]); ``opacity`` is kept as the material has it."""
    if isinstance(node, AnimationFrameVisualizer):
        node["<object>"].set_property("material.color", "color", [float(c) for c in color])
    else:
        node.set_property("color", [*map(float, color), opacity])


def rotation_onto(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector a onto unit vector b."""
    axis = np.cross(a, b)
    sine, cosine = np.linalg.norm(axis), float(a @ b)
    if sine < 1e-12:
        if cosine > 0:
            return np.eye(3)
        # opposite: half a turn about any axis perpendicular to a
        other = np.eye(3)[int(np.argmin(np.abs(a)))]
        perpendicular = np.cross(a, other) / np.linalg.norm(np.cross(a, other))
        return pin.exp3(np.pi * perpendicular)
    return pin.exp3(axis / sine * math.atan2(sine, cosine))
