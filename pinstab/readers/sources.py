"""Where robot descriptions come from: the bundled scenes and the robots of example-robot-data."""

from __future__ import annotations

import sysconfig
from functools import lru_cache
from pathlib import Path

from ..errors import SceneError, choices


def bundled_dir() -> Path:
    """The folder holding the bundled scenes (``robots/`` of the source tree or the wheel)."""
    package = Path(__file__).resolve().parents[1]
    for candidate in (package / "robots", package.parent / "robots"):  # the wheel's copy, the source tree's
        if candidate.is_dir():
            return candidate
    raise SceneError("the bundled robots/ folder is missing from this installation of pinstab")


def bundled_scenes() -> dict[str, Path]:
    """Bundled scene names mapped to their TOML files."""
    return {path.stem: path for path in sorted(bundled_dir().glob("*.toml"))}


@lru_cache(maxsize=1)
def example_robot_data_dir() -> Path | None:
    """The ``robots`` folder that the ``example-robot-data`` package installs, if present."""
    roots = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    for root in roots:
        candidate = Path(root) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if candidate.is_dir():
            return candidate
    return None


def example_robot_names() -> dict[str, Path]:
    """example-robot-data robot names mapped to their files: every ``<name>.urdf`` in a description's
    ``urdf/`` or ``robots/`` folder (``panda``, ``ur5``, ``allegro_right_hand``, ``finger_edu``, ...), then
    every ``<name>.sdf`` there whose name no URDF has (``cassie``, ``cassie_v2``, ...)."""
    base = example_robot_data_dir()
    if base is None:
        return {}
    names: dict[str, Path] = {}
    for description in sorted(base.glob("*_description")):
        for suffix in ("urdf", "sdf"):
            for path in sorted([*description.glob(f"urdf/*.{suffix}"), *description.glob(f"robots/*.{suffix}")]):
                names.setdefault(path.stem, path)
    return names


def example_robot_urdf(name: str) -> tuple[Path, Path]:
    """Resolve an example-robot-data robot by name.

    Returns:
        (URDF or SDF file, package directory to search for ``package://`` meshes).
    """
    names = example_robot_names()
    if name not in names:
        if not names:
            raise SceneError(
                f"robot {name!r}: the example-robot-data package is not installed (pip install example-robot-data)"
            )
        raise SceneError(f"unknown example-robot-data robot {name!r}; valid names: {choices(names)}")
    return names[name], names[name].parents[2]
