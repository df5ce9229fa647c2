"""Robot readers: the room for "load a robot". A scene's ``[robot]`` table names one source: a URDF file
(``urdf``) or document (``urdf_text``), another format registered in :data:`READERS` (one module each), or an
example-robot-data robot by ``name``; :func:`read_robot` returns a :class:`RobotSource`."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..constraints.joint_limits import check_limit_bounds
from ..errors import SceneError, choices
from ..registry import load_extensions
from .base import READERS, ReaderOptions, RobotSource
from .sources import bundled_dir, bundled_scenes, example_robot_data_dir, example_robot_names, example_robot_urdf
from .urdf import read_named

load_extensions(__name__, __path__)

URDF_KEYS = ("urdf", "urdf_text")  # the source keys of URDF documents, which copies are made of
ROBOT_KEYS = {
    "name",
    "free_flyer",
    "locked_joints",
    "copies",
    "ignore_limits",
    "keyframe",
    "ctrl",
}  # with one key per reader (READERS)


def read_robot(robot: dict[str, Any], base_dir: Path) -> RobotSource:
    """The robot of a scene's ``[robot]`` table (exactly one source key), its relative paths read from ``base_dir``.

    Raises:
        SceneError: no source or several, an unknown robot name, a file that cannot be read (named), a joint
            whose lower limit is above its upper one (named).
    """
    source = _read(robot, base_dir)
    check_limit_bounds(source.model)
    return source


def _read(robot: dict[str, Any], base_dir: Path) -> RobotSource:
    sources = [key for key in robot if key in READERS or key == "name"]
    if len(sources) != 1:
        given = f"; given: {', '.join(sources)}" if sources else ""
        raise SceneError(
            f"robot: give exactly one of 'name' (an example-robot-data robot) or a file: {choices(READERS)}{given}"
        )
    free_flyer = robot.get("free_flyer", False)
    if not isinstance(free_flyer, bool):
        raise SceneError(f"robot.free_flyer must be true or false, got {free_flyer!r}")
    options = ReaderOptions(base_dir, free_flyer)
    if sources[0] != "name":
        _refuse_copies(robot, sources[0])
        _refuse_keyframe(robot, sources[0])
        return READERS.entry(sources[0]).factory(robot, options)
    if not isinstance(robot["name"], str):
        raise SceneError(f"robot.name must be a string, got {robot['name']!r}")
    path, package_dir = example_robot_urdf(robot["name"])
    if path.suffix != ".urdf":  # another format: the reader registered for its suffix
        reader = next(entry for entry in READERS.entries() if path.suffix in entry.capabilities)
        _refuse_copies(robot, reader.name)
        _refuse_keyframe(robot, reader.name)
        return reader.factory({**robot, reader.name: str(path)}, options)
    _refuse_keyframe(robot, "urdf")
    # meshes are named package://example-robot-data/robots/...: the share/ folder resolves them
    package_dirs = [str(package_dir), str(package_dir.parent), str(package_dir.parent.parent)]
    return read_named(robot, options, path, package_dirs)


def _refuse_copies(robot: dict[str, Any], format: str) -> None:
    """``robot.copies`` of a robot read in ``format``: copies are made of URDF documents only.

    Raises:
        SceneError: naming the format and where copies can be made.
    """
    if "copies" in robot and format not in URDF_KEYS:
        raise SceneError(
            f"robot.copies: copies of a robot are made from a URDF (robot.urdf, robot.urdf_text or a URDF robot.name), "
            f"not {format.upper()}"
        )


def _refuse_keyframe(robot: dict[str, Any], format: str) -> None:
    """``robot.keyframe`` or ``robot.ctrl`` of a robot read in ``format``: keyframes and actuators are read from MJCF
    files only.

    Raises:
        SceneError: naming the key and the format.
    """
    for key, what in (("keyframe", "keyframes"), ("ctrl", "actuators' controls")):
        if key in robot and format != "mjcf":
            raise SceneError(f"robot.{key}: {what} are read from MJCF files (robot.mjcf), not {format.upper()}")


__all__ = [
    "READERS",
    "ROBOT_KEYS",
    "ReaderOptions",
    "RobotSource",
    "bundled_dir",
    "bundled_scenes",
    "example_robot_data_dir",
    "example_robot_names",
    "example_robot_urdf",
    "read_robot",
]
