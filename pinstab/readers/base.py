"""A robot read from a description file: the Pinocchio model, what the scene gains from the file (loop closures,
joint relations, springs as scene tables), and how its geometry is built."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pinocchio as pin

from ..registry import Registry


@dataclass
class RobotSource:
    """A robot as its reader built it.

    Attributes:
        model: the full kinematic tree (depth-first joint order), every joint and frame named as in the file.
        format: ``urdf``, ``sdf``, ``mjcf``, ... (the reader's name).
        path: the file read (None for a document given as text).
        urdf_path, urdf_text: the URDF document the model was built from, when there is one (a SDF reader may write
            one), for the visual geometry; package_dirs: where ``package://`` meshes are found.
        tables: scene tables the file declares, by scene array (``closures``, ``forces``): read like the scene's
            own entries, before them, so that every name of the file is kept.
        notes: what the reader left out or changed, in words (reported by ``pinstab check``).
        geometry: ``geometry(model, kind, package_dirs)`` builds the geometry of ``model`` of a kind (visual,
            collision), meshes found in ``package_dirs``; None: the file has no geometry.
    """

    model: pin.Model
    format: str
    path: Path | None = None
    urdf_path: Path | None = None
    urdf_text: str | None = None
    package_dirs: list[str] = field(default_factory=list)
    tables: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    geometry: Callable[[pin.Model, pin.GeometryType, list[str]], pin.GeometryModel] | None = None


@dataclass(frozen=True)
class ReaderOptions:
    """What every reader is given besides the robot table.

    Attributes:
        base_dir: the folder relative paths of the scene are read from.
        free_flyer: put the robot's root on a free-flyer joint.
    """

    base_dir: Path = Path(".")
    free_flyer: bool = False


def robot_geometry(
    robot: RobotSource | None,
    full: pin.Model,
    locked: dict[str, float],
    kind: pin.GeometryType,
    package_dirs: list[str] | None = None,
) -> pin.GeometryModel:
    """The robot's geometry of ``kind`` (visual or collision), built by its reader for the full model (meshes found
    in ``package_dirs``, default the reader's) and reduced with the joints ``locked`` at their positions [rad or m],
    so that its joint and frame indices are those of the scene's model; empty when the reader builds none.

    Raises:
        ValueError, RuntimeError: the reader cannot build it (a mesh missing, ...).
    """
    if robot is None or robot.geometry is None:
        return pin.GeometryModel()
    geometry = robot.geometry(full, kind, robot.package_dirs if package_dirs is None else package_dirs)
    if not locked:
        return geometry
    reference = pin.neutral(full)
    for joint, position in locked.items():
        reference[full.joints[full.getJointId(joint)].idx_q] = position
    _, reduced = pin.buildReducedModel(full, geometry, [full.getJointId(joint) for joint in locked], reference)
    return reduced


# key of the [robot] table naming the file (``urdf = "arm.urdf"``) -> reader(robot table, options) -> RobotSource;
# a reader's capabilities are the file suffixes it reads (for ``name`` = an example-robot-data robot)
READERS: Registry[RobotSource] = Registry("robot format")
