"""The visual geometry of a scene's (reduced) model, from its URDF."""

from __future__ import annotations

import pinocchio as pin

from ..errors import SceneError
from ..scene import Scene


def visual_model(scene: Scene) -> pin.GeometryModel:
    """Visual geometry objects (meshes and primitives) attached to ``scene.model``'s frames.

    Built from the scene's URDF for the full model and reduced with the same locked joints, so its
    frame indices are those of ``scene.model`` (the closure frames the scene adds come after them).
    """
    full = scene.full_model if scene.full_model is not None else scene.model
    try:
        if scene.urdf_text is not None:
            geometry = pin.buildGeomFromUrdfString(full, scene.urdf_text, pin.GeometryType.VISUAL)
        else:
            geometry = pin.buildGeomFromUrdf(
                full, str(scene.urdf_path), pin.GeometryType.VISUAL, package_dirs=scene.package_dirs
            )
    except (ValueError, RuntimeError) as exc:
        raise SceneError(f"scene {scene.name}: the URDF's visual geometry cannot be loaded: {exc}") from None
    if not scene.locked_joints:
        return geometry
    reference = pin.neutral(full)
    for joint, position in scene.locked_joints.items():
        reference[full.joints[full.getJointId(joint)].idx_q] = position
    locked = [full.getJointId(joint) for joint in scene.locked_joints]
    _, reduced = pin.buildReducedModel(full, geometry, locked, reference)
    return reduced
