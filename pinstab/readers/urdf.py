"""URDF robots: a file, a document given as text (``urdf_text``), several prefixed copies."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import coal
import pinocchio as pin

from ..errors import SceneError
from .base import READERS, ReaderOptions, RobotSource
from .bounds import read_bounded
from .copies import compose_copies, parse_copies
from .urdf_checks import check_links

# meshes read once per process and file (copies of a robot share them; the collision checks and the viewer reuse
# them), keyed by file and scale, with the modification time it was read at
MESHES = coal.CachedMeshLoader()


def read_urdf(robot: dict[str, Any], options: ReaderOptions) -> RobotSource:
    """The robot of ``robot.urdf`` (a path relative to the scene) or ``robot.urdf_text``, with ``robot.copies``.

    Raises:
        SceneError: a missing file, a document urdfdom cannot read, a link with a non-physical inertia.
    """
    urdf_text = robot.get("urdf_text")
    urdf_path = None
    package_dirs: list[str] = []
    if urdf_text is None:
        urdf_path = resolve_file(robot, "urdf", options)
        package_dirs = [str(urdf_path.parent)]
    return _build(robot, options, urdf_path, None if urdf_text is None else str(urdf_text), package_dirs)


def read_named(robot: dict[str, Any], options: ReaderOptions, path, package_dirs: list[str]) -> RobotSource:
    """An example-robot-data URDF robot (its inertias taken as published: no triangle inequality)."""
    return _build(robot, options, path, None, package_dirs, triangle=False)


def read_body(value: Any, where: str, base_dir: Path) -> tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]:
    """The model, collision and visual geometry of the URDF file ``value`` (a path relative to ``base_dir``, meshes
    found next to it) given at ``where`` in a scene table other than ``[robot]`` (an object's ``urdf``: ``object
    'crate'.urdf``), held to the checks of the scene's own robot URDF (:func:`.urdf_checks.check_links`).

    Raises:
        SceneError: naming ``where``: not a path, a missing file, one beyond the bounds of :mod:`.bounds`, not UTF-8,
            a link with a non-physical inertia, a document urdfdom cannot read, a mesh that cannot be loaded.
    """
    path = _file(value, base_dir, where)
    source = _build({}, ReaderOptions(base_dir), path, None, [str(path.parent)], owner=where)
    try:
        collision, visual = (
            source.geometry(source.model, kind, source.package_dirs)
            for kind in (pin.GeometryType.COLLISION, pin.GeometryType.VISUAL)
        )
    except (ValueError, RuntimeError) as exc:
        raise SceneError(f"{where}: the URDF cannot be read: {exc}") from None
    return source.model, collision, visual


def resolve_file(robot: dict[str, Any], key: str, options: ReaderOptions) -> Path:
    """The path ``robot[key]``, relative to the scene's folder; SceneError when it is not a file."""
    return _file(robot[key], options.base_dir, f"robot.{key}")


def _file(value: Any, base_dir: Path, where: str) -> Path:
    """The file ``value`` names, relative to ``base_dir``; SceneError naming ``where`` when it is not one."""
    if not isinstance(value, str):
        raise SceneError(f"{where} must be a path string, got {value!r}")
    path = (base_dir / value).resolve()
    if not path.is_file():
        raise SceneError(f"{where}: file {path} does not exist")
    return path


def _build(
    robot, options: ReaderOptions, urdf_path, urdf_text, package_dirs, triangle: bool = True, owner: str = "robot"
) -> RobotSource:
    if "copies" in robot:  # one document of prefixed copies; package_dirs still resolve the meshes
        copies = parse_copies(robot["copies"])
        source = read_bounded(urdf_path, f"robot: URDF {urdf_path}") if urdf_text is None else urdf_text
        urdf_text = compose_copies(source, copies)
        urdf_path = None
    check_links(urdf_text, urdf_path, triangle, owner)  # names what urdfdom would only refuse
    root = [pin.JointModelFreeFlyer()] if options.free_flyer else []
    try:
        if urdf_text is not None:
            model = pin.buildModelFromXML(urdf_text, *root)
        else:
            model = pin.buildModelFromUrdf(str(urdf_path), *root)
    except (ValueError, RuntimeError) as exc:
        raise SceneError(f"{owner}: the URDF cannot be read: {exc}") from None

    def geometry(full: pin.Model, kind: pin.GeometryType, search: list[str]) -> pin.GeometryModel:
        if urdf_text is not None:
            return pin.buildGeomFromUrdfString(full, urdf_text, kind, package_dirs=search, mesh_loader=MESHES)
        return pin.buildGeomFromUrdf(full, str(urdf_path), kind, package_dirs=search, mesh_loader=MESHES)

    return RobotSource(model, "urdf", urdf_path, urdf_path, urdf_text, package_dirs, geometry=geometry)


READERS.register(
    "urdf", read_urdf, summary="a URDF file (robot.urdf) or document (robot.urdf_text)", capabilities={".urdf"}
)
READERS.register("urdf_text", read_urdf, summary="a URDF document given in the scene")
