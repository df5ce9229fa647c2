"""A robot read from a description file: the Pinocchio model, what the scene gains from the file (loop closures,
joint relations, springs as scene tables), and how its geometry is built."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ..registry import Registry

RENAMED = "#body"  # appended to a body frame's name while a joint of its name is locked (reduce_model)


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
        start: the start the file gives, (q, v) of ``model`` [rad, m; rad/s, m/s] (an MJCF keyframe or MuJoCo's
            qpos0); None: the neutral configuration at rest.
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
    start: tuple[np.ndarray, np.ndarray] | None = None


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
    return reduce_model(full, [full.getJointId(joint) for joint in locked], reference, geometry)[1]


def robot_start(robot: RobotSource | None, model: pin.Model) -> tuple[np.ndarray, np.ndarray]:
    """The start (q, v) [rad, m; rad/s, m/s] the robot's file gives, of ``model`` (the robot's model reduced by
    locked joints: each joint's coordinates by its name), or the neutral configuration at rest."""
    q, v = pin.neutral(model), np.zeros(model.nv)
    if robot is None or robot.start is None:
        return q, v
    full = robot.model
    for joint in range(1, model.njoints):
        if not full.existJointName(model.names[joint]):
            continue
        given, own = full.joints[full.getJointId(model.names[joint])], model.joints[joint]
        q[own.idx_q : own.idx_q + own.nq] = robot.start[0][given.idx_q : given.idx_q + given.nq]
        v[own.idx_v : own.idx_v + own.nv] = robot.start[1][given.idx_v : given.idx_v + given.nv]
    return q, v


def reduce_model(
    full: pin.Model, locked: list[int], q: np.ndarray, geometry: pin.GeometryModel | None = None
) -> tuple[pin.Model, pin.GeometryModel | None]:
    """``pin.buildReducedModel`` of ``full`` (and of ``geometry``, when given) with the joints ``locked`` at ``q``
    [rad or m]. Where a body frame shares its name with a joint (an MJCF body and its joint, as in the bundled
    four-bar), Pinocchio 4.1 fails to tell the joint's frame from the body's (``Several frames match``): such body
    frames are renamed for the reduction and named back after it."""
    names = set(full.names)
    model = full.copy()
    renamed: dict[str, str] = {}
    for index, frame in enumerate(model.frames):
        if frame.name in names and frame.type == pin.FrameType.BODY:
            renamed[f"{frame.name}{RENAMED}"] = frame.name
            frame.name += RENAMED
            model.frames[index] = frame
    if geometry is None:
        reduced, reduced_geometry = pin.buildReducedModel(model, locked, q), None
    else:
        reduced, reduced_geometry = pin.buildReducedModel(model, geometry, locked, q)
    for index, frame in enumerate(reduced.frames):
        if frame.name in renamed:
            frame.name = renamed[frame.name]
            reduced.frames[index] = frame
    return reduced, reduced_geometry


# key of the [robot] table naming the file (``urdf = "arm.urdf"``) -> reader(robot table, options) -> RobotSource;
# a reader's capabilities are the file suffixes it reads (for ``name`` = an example-robot-data robot)
READERS: Registry[RobotSource] = Registry("robot format")
