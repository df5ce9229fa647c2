"""What an SDF model adds to its scene, as scene-table entries named after the SDF joints.

- A loop joint (its child already has a parent) becomes a closure at the joint frame, between a frame on the
  child link (``frame_a``) and one on the parent link (``frame_b``): ``ball`` -> ``point`` (3 rows),
  ``revolute``/``continuous`` -> ``revolute`` (5 rows, the rotation about ``axis`` free), ``prismatic`` ->
  ``prismatic`` (5 rows, the translation along ``axis`` free), ``fixed`` -> ``weld`` (6 rows).
- A ``gearbox`` (parent turning by theta_1 and child by theta_2 about their axes relative to the reference
  body, SDF: ``theta_2 = -gearbox_ratio theta_1``) becomes the ``joint-relation``
  ``ratio theta_1 + theta_2 = 0`` over the two tree joints that hang them from the reference body.
- ``<dynamics>`` damping and ``<spring_stiffness>``/``<spring_reference>`` of a tree joint become a
  ``joint-spring`` force named ``<joint>/dynamics``; on a loop joint, a ``joint-spring`` between the closure's
  two frames along its free axis. Joint friction is left out (a note).
"""

from __future__ import annotations

from typing import Any

import pinocchio as pin

from ..errors import SceneError
from .sdf_document import SdfJoint, SdfModel, rpy_of
from .sdf_tree import SdfTree, axis_sign

CLOSURE_OF = {
    "ball": "point",
    "revolute": "revolute",
    "continuous": "revolute",
    "prismatic": "prismatic",
    "fixed": "weld",
}
ONE_DOF = ("revolute", "continuous", "prismatic")


def _vector(values) -> list[float]:
    return [float(x) for x in values]


def _ends(joint: SdfJoint, sdf: SdfModel) -> dict[str, Any]:
    """``frame_a`` on the child, ``frame_b`` on the parent (or the world), both at the joint frame."""
    entry: dict[str, Any] = {}
    for suffix, link in (("a", joint.child), ("b", joint.parent)):
        origin = sdf.links[link].pose if link in sdf.links else pin.SE3.Identity()
        offset = origin.actInv(joint.placement)
        entry[f"frame_{suffix}"] = link
        entry[f"offset_{suffix}"] = _vector(offset.translation)
        entry[f"rpy_{suffix}"] = rpy_of(offset)
    return entry


def _axis_in_joint(joint: SdfJoint) -> list[float]:
    return _vector(joint.placement.rotation.T @ joint.axis)


def closure_entry(joint: SdfJoint, sdf: SdfModel) -> dict[str, Any]:
    """The ``closures`` entry of a loop joint (not a gearbox)."""
    entry = {"name": joint.name, "kind": CLOSURE_OF[joint.type], **_ends(joint, sdf)}
    if joint.type in ONE_DOF:
        entry["axis"] = _axis_in_joint(joint)
    return entry


def gearbox_entry(joint: SdfJoint, tree: SdfTree) -> dict[str, Any]:
    """The ``joint-relation`` entry of a gearbox joint.

    Raises:
        SceneError: its parent or child does not hang from the reference body by a 1-DOF joint parallel to the
            gearbox's axis.
    """
    where = f"sdf gearbox joint {joint.name!r}"
    coefficients = {}
    for link, axis, factor in ((joint.parent, joint.axis, joint.gearbox_ratio), (joint.child, joint.axis2, 1.0)):
        hinge = tree.parent_joint.get(link)
        if hinge is None or hinge.parent != joint.gearbox_reference or hinge.type not in ONE_DOF:
            raise SceneError(
                f"{where}: link {link!r} must hang from the gearbox_reference_body {joint.gearbox_reference!r} "
                "by a 1-DOF joint"
            )
        coefficients[hinge.name] = factor * axis_sign(hinge, axis, where)
    return {"name": joint.name, "kind": "joint-relation", "joints": coefficients, "value": 0.0}


def spring_entry(joint: SdfJoint, sdf: SdfModel, loop: bool) -> dict[str, Any]:
    """The ``joint-spring`` force of a joint's ``<dynamics>``: on the joint, or between a closure's frames."""
    entry: dict[str, Any] = {"name": f"{joint.name}/dynamics", "kind": "joint-spring"}
    if loop:
        motion = "prismatic" if joint.type == "prismatic" else "revolute"
        entry.update(_ends(joint, sdf), axis=_axis_in_joint(joint), motion=motion)
    else:
        entry["joint"] = joint.name
    if joint.stiffness:
        entry.update(stiffness=joint.stiffness, reference=joint.reference)
    if joint.damping:
        entry["damping"] = joint.damping
    return entry


def scene_tables(sdf: SdfModel, tree: SdfTree, notes: list[str]) -> dict[str, list[dict[str, Any]]]:
    """The ``closures`` and ``forces`` entries of ``sdf``; what is left out is appended to ``notes``."""
    closures, forces = [], []
    loops = {joint.name for joint in tree.loops}
    for joint in sdf.joints:
        loop = joint.name in loops
        if joint.type == "gearbox":
            closures.append(gearbox_entry(joint, tree))
            continue
        if loop:
            closures.append(closure_entry(joint, sdf))
        if joint.friction:
            notes.append(f"joint {joint.name!r}: friction {joint.friction} left out (pinstab has no joint friction)")
        if not (joint.stiffness or joint.damping):
            continue
        if joint.type == "fixed" or (joint.type == "ball" and (loop or joint.stiffness)):
            notes.append(f"joint {joint.name!r}: the <dynamics> of a {joint.type} joint are left out")
            continue
        forces.append(spring_entry(joint, sdf, loop))
    return {key: value for key, value in (("closures", closures), ("forces", forces)) if value}
