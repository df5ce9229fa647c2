"""``pinstab inspect``: list what a scene's robot is made of, as its Pinocchio model holds it (joints with their
limits, frames, bodies with their inertia, collision geometry) and the scene's objects, constraints, forces and
locked joints: the names the scene files and the API take. A robot file (URDF, SDF, MJCF) is listed as it is read.

Nothing is assembled or simulated (a scene whose closures do not assemble lists too)."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ...errors import SceneError
from ..options import parameters
from .base import Command, register

if TYPE_CHECKING:
    import pinocchio as pin

    from ...scene import Scene

ROBOT_FILES = {".urdf": "urdf", ".sdf": "sdf", ".xml": "mjcf", ".mjcf": "mjcf"}  # suffix -> [robot] key
UNBOUNDED = float(np.finfo(float).max)  # what Pinocchio's readers store for a limit not given


def arguments(parser: argparse.ArgumentParser) -> None:
    """The scene or robot file, ``--param``, ``--json``."""
    parser.add_argument(
        "scene",
        help="bundled scene name (fourbar, cassie, ...), a .toml scene file, or a robot file: "
        f"{', '.join(ROBOT_FILES)} (MJCF: .xml)",
    )
    parser.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE", help="scene generator parameter, e.g. N=20"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def inspect(args: argparse.Namespace) -> dict[str, Any]:
    """The listing of :func:`listing` for the scene or robot file ``args.scene``."""
    return listing(_scene(args.scene, parameters(args.param)))


def _scene(argument: str, given: dict[str, Any]) -> Scene:
    """The scene named or read from ``argument``; a robot file makes a scene of its robot alone (the file's own
    closures, relations and springs included).

    Raises:
        SceneError: a file that is neither a scene nor a robot file (naming the suffixes read), ``--param``
            given with a robot file, or what :func:`~pinstab.scene.load_scene` refuses.
    """
    from ...scene import load_scene, scene_from_dict

    path = Path(argument)
    if path.suffix.lower() in ROBOT_FILES and not path.is_file():
        raise SceneError(f"robot file {argument} does not exist")
    if path.suffix == ".toml" or not path.is_file():
        return load_scene(argument, **given)
    if path.suffix.lower() not in ROBOT_FILES:
        raise SceneError(
            f"{argument}: not a scene (.toml) nor a robot file ({', '.join(ROBOT_FILES)}); give one of those or a "
            "bundled scene name"
        )
    if given:
        raise SceneError(f"--param {next(iter(given))}: a robot file ({argument}) has no generator to take it")
    robot = {ROBOT_FILES[path.suffix.lower()]: str(path.resolve())}
    return scene_from_dict({"robot": robot}, name=path.stem, source=path)


def listing(scene: Scene) -> dict[str, Any]:
    """What ``pinstab inspect`` prints: the scene's model (joints, frames, bodies) as lists in Pinocchio's order,
    its collision geometry, objects, constraints, forces and locked joints. Limits Pinocchio's readers store as
    "none given" (the largest double) or infinite are None."""
    model = scene.model
    robot = scene.robot
    return {
        "scene": scene.name,
        "robot_format": None if robot is None else robot.format,
        "robot_file": None if robot is None or robot.path is None else str(robot.path),
        "nq": model.nq,
        "nv": model.nv,
        "total_mass": float(sum(inertia.mass for inertia in model.inertias[1:])),  # the world's links left out
        "joints": _joints(model),
        "frames": [
            {
                "name": frame.name,
                "type": frame.type.name,
                "parent_joint": model.names[frame.parentJoint],
                "parent_frame": model.frames[frame.parentFrame].name,
            }
            for frame in model.frames
        ],
        "bodies": _bodies(model),
        "collision_geometry": _geometry(scene),
        "objects": [{"name": item.name, "shape": item.shape, "mass": item.mass} for item in scene.objects],
        "constraints": [
            {
                "name": constraint.name,
                "kind": getattr(constraint, "kind", None) or type(constraint).__name__,
                "rows": constraint.rows,
                "row_kind": constraint.row_kind.value,
                "holonomic": constraint.holonomic,
                "prescribed": constraint.prescribed,
                "force_frame": constraint.force_frame,
            }
            for constraint in scene.constraints
        ],
        "forces": [
            {"name": element.name, "kind": getattr(element, "kind", None) or type(element).__name__}
            for element in scene.forces
        ],
        "locked_joints": scene.locked_joints,
    }


def _joints(model: pin.Model) -> list[dict[str, Any]]:
    """Each joint but the universe: type (Pinocchio's, ``RZ``, ``FreeFlyer``, ...), parent joint, indices, position
    limits [rad or m] (None on a side bounded by the largest double, or why there are none), velocity [rad/s or
    m/s] and effort [N m or N] limits per velocity coordinate."""
    from ...constraints.joint_limits import joint_limits

    limits = joint_limits(model)
    ranges = limits.ranges()
    joints = []
    for j in range(1, model.njoints):
        joint, name = model.joints[j], model.names[j]
        velocities = slice(joint.idx_v, joint.idx_v + joint.nv)
        joints.append(
            {
                "name": name,
                "type": joint.shortname().removeprefix("JointModel"),
                "parent": model.names[model.parents[j]],
                "idx_q": joint.idx_q,
                "idx_v": joint.idx_v,
                "nq": joint.nq,
                "nv": joint.nv,
                "position_limit": None if name not in ranges else _bounds(ranges[name]),
                "unlimited": limits.unlimited.get(name),
                "velocity_limit": _bounds(model.velocityLimit[velocities]),
                "effort_limit": _bounds(model.effortLimit[velocities]),
            }
        )
    return joints


def _bounds(values: Sequence[float]) -> list[float | None]:
    """Limits as floats, None where Pinocchio stores none (infinite or the largest double)."""
    return [float(x) if math.isfinite(x) and abs(x) < UNBOUNDED else None for x in values]


def _bodies(model: pin.Model) -> list[dict[str, Any]]:
    """The rigid body each joint moves (the links fixed to it merged, as Pinocchio holds it): mass [kg], centre of
    mass in the joint's frame [m], principal moments of inertia about it [kg m^2], and its links (BODY frames); the
    links fixed to the world first (joint ``universe``), when they have mass."""
    import pinocchio as pin

    bodies = []
    for j in range(model.njoints):
        inertia = model.inertias[j]
        if j == 0 and inertia.mass == 0.0:
            continue
        links = [f.name for f in model.frames if f.parentJoint == j and f.type == pin.FrameType.BODY]
        bodies.append(
            {
                "joint": model.names[j],
                "mass": float(inertia.mass),
                "com": inertia.lever.tolist(),
                "principal_inertia": np.linalg.eigvalsh(inertia.inertia).tolist(),
                "links": links,
            }
        )
    return bodies


def _geometry(scene: Scene) -> dict[str, Any]:
    """The robot's collision geometry as its reader builds it for the scene's model: ``loaded`` (the geometry
    objects: shape, parent joint and frame, mesh file) or why there is none (``note``)."""
    import pinocchio as pin

    from ...readers.base import robot_geometry

    robot = scene.robot
    if robot is None or robot.geometry is None:
        reader = "this robot's" if robot is None else f"the {robot.format} reader"
        return {"loaded": False, "note": f"none: {reader} builds no collision geometry", "geometries": []}
    try:
        geometry = robot_geometry(robot, scene.full_model, scene.locked_joints, pin.GeometryType.COLLISION)
    except (ValueError, RuntimeError) as exc:
        return {"loaded": False, "note": f"not loaded: {exc}", "geometries": []}
    objects = [
        {
            "name": item.name,
            "shape": type(item.geometry).__name__,
            "parent_joint": scene.model.names[item.parentJoint],
            "parent_frame": scene.model.frames[item.parentFrame].name,
            "mesh": Path(item.meshPath).name if Path(item.meshPath).suffix else None,  # primitives: its shape's name
        }
        for item in geometry.geometryObjects
    ]
    note = f"{len(objects)} objects" if objects else f"none: the {robot.format} file declares no collision elements"
    return {"loaded": bool(objects), "note": note, "geometries": objects}


def text(result: dict[str, Any]) -> str:
    """The listing as tables a person reads."""
    file = f" ({result['robot_file']})" if result["robot_file"] else ""
    lines = [
        f"scene {result['scene']}: robot read as {result['robot_format']}{file}; nq = {result['nq']}, "
        f"nv = {result['nv']}, moving mass {result['total_mass']:.6g} kg"
    ]
    joint_rows = [
        [
            joint["name"],
            joint["type"],
            joint["parent"],
            f"{joint['idx_q']}/{joint['idx_v']}",
            _range(joint),
            _values(joint["velocity_limit"]),
            _values(joint["effort_limit"]),
        ]
        for joint in result["joints"]
    ]
    headers = ["name", "type", "parent", "q/v index", "position [rad|m]", "velocity [/s]", "effort [N m|N]"]
    lines += _section(f"joints ({len(joint_rows)})", headers, joint_rows)
    frame_rows = [[f["name"], f["type"], f["parent_joint"], f["parent_frame"]] for f in result["frames"]]
    lines += _section(f"frames ({len(frame_rows)})", ["name", "type", "parent joint", "parent frame"], frame_rows)
    body_rows = [
        [
            body["joint"],
            f"{body['mass']:.6g}",
            _vector(body["com"]),
            _vector(body["principal_inertia"]),
            ", ".join(body["links"]) or "-",
        ]
        for body in result["bodies"]
    ]
    headers = ["joint", "mass [kg]", "com [m]", "principal inertia [kg m^2]", "links"]
    lines += _section(f"bodies ({len(body_rows)}, links fixed together merged)", headers, body_rows)
    geometry = result["collision_geometry"]
    rows = [
        [g["name"], g["shape"], g["parent_joint"], g["parent_frame"], g["mesh"] or "-"] for g in geometry["geometries"]
    ]
    headers = ["name", "shape", "parent joint", "parent frame", "mesh"]
    lines += _section(f"collision geometry: {geometry['note']}", headers, rows)
    rows = [[o["name"], o["shape"], f"{o['mass']:.6g}"] for o in result["objects"]]
    lines += _section(f"objects ({len(rows)})", ["name", "shape", "mass [kg]"], rows)
    rows = [
        [
            c["name"],
            c["kind"],
            str(c["rows"]),
            c["row_kind"] + (", prescribed" if c["prescribed"] else ""),
            c["force_frame"],
        ]
        for c in result["constraints"]
    ]
    lines += _section(f"constraints ({len(rows)})", ["name", "kind", "rows", "row kind", "force frame"], rows)
    rows = [[f["name"], f["kind"]] for f in result["forces"]]
    lines += _section(f"forces ({len(rows)})", ["name", "kind"], rows)
    rows = [[name, f"{position:.6g}"] for name, position in result["locked_joints"].items()]
    lines += _section(f"locked joints ({len(rows)})", ["name", "at [rad|m]"], rows)
    return "\n".join(lines)


def _range(joint: dict[str, Any]) -> str:
    """A joint's position range, or ``none: <why>``."""
    if joint["position_limit"] is None:
        return f"none: {joint['unlimited']}"
    lower, upper = joint["position_limit"]
    return f"[{'-inf' if lower is None else f'{lower:.6g}'}, {'inf' if upper is None else f'{upper:.6g}'}]"


def _values(values: Sequence[float | None]) -> str:
    """One value, or several in brackets (one when all are equal); ``-`` for none given."""
    shown = ["-" if x is None else f"{x:.6g}" for x in values]
    if len(set(shown)) == 1:
        return shown[0]
    return f"[{', '.join(shown)}]"


def _vector(values: Sequence[float]) -> str:
    """A vector's entries in brackets, 4 significant digits."""
    return f"[{', '.join(f'{x:.4g}' for x in values)}]"


def _section(title: str, headers: list[str], rows: list[list[str]]) -> list[str]:
    """A titled table (columns as wide as their widest cell), or the title alone without rows."""
    if not rows:
        return ["", title]
    widths = [max(len(cell) for cell in column) for column in zip(headers, *rows, strict=True)]
    table = [headers, *rows]
    return ["", f"{title}:"] + [
        "  " + "  ".join(f"{c:<{w}}" for c, w in zip(r, widths, strict=True)).rstrip() for r in table
    ]


register(
    Command(
        "inspect",
        "list a scene's robot (joints, limits, frames, bodies, collision geometry) and its constraints",
        arguments,
        inspect,
        text=text,
        order=0,
    )
)
