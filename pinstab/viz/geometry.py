"""The visual geometry of a scene's (reduced) model, from its robot's file, and of its objects."""

from __future__ import annotations

import pinocchio as pin

from ..errors import SceneError
from ..readers.base import robot_geometry
from ..scene import Scene


def visual_model(scene: Scene) -> pin.GeometryModel:
    """Visual geometry objects (meshes and primitives) attached to ``scene.model``'s frames.

    Built by the scene's robot reader (a URDF: ``package://`` meshes found in ``scene.package_dirs``) for
    the full model and reduced with the same locked joints, so its frame indices are those of
    ``scene.model`` (the closure frames the scene adds come after them); then the visuals of the scene's
    objects, already attached to their joints in ``scene.model``.
    """
    geometry = _robot_geometry(scene)
    for item in scene.objects:
        for visual in item.visuals:
            geometry.addGeometryObject(visual)
    return geometry


def _robot_geometry(scene: Scene) -> pin.GeometryModel:
    """The robot's visuals, reduced like ``scene.model``."""
    full = scene.full_model if scene.full_model is not None else scene.model
    try:
        return robot_geometry(scene.robot, full, scene.locked_joints, pin.GeometryType.VISUAL, scene.package_dirs)
    except (ValueError, RuntimeError) as exc:
        raise SceneError(
            f"scene {scene.name}: the {scene.robot.format.upper()}'s visual geometry cannot be loaded: {exc}"
        ) from None
