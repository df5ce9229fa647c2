"""Scenes: a robot (reduced to what the scene needs), loop closures, force elements, initial state.

A scene is read from a TOML file (or a bundled scene by name) by :func:`load_scene`. Scene files
are data: nothing in them is evaluated. See ``robots/*.toml`` for examples and README for the
schema.
"""

from __future__ import annotations

import copy
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from . import robots
from .constraints import CLOSURE_KINDS, Constraint, ConstraintSet, FrameClosure
from .constraints.loops import PLANES
from .errors import SceneError, choices
from .forces import ForceElement, JointTorque, SpringDamper
from .generators import generate
from .units import quantity

WORLD = "world"
TOP_KEYS = {"name", "description", "robot", "generator", "gravity", "closures", "forces", "initial"}
ROBOT_KEYS = {"urdf", "name", "urdf_text", "free_flyer", "locked_joints"}
CLOSURE_KEYS = {"name", "kind", "frame_a", "offset_a", "rpy_a", "frame_b", "offset_b", "rpy_b", "plane"}
TORQUE_KEYS = {"name", "kind", "joint", "torque", "table"}
SPRING_KEYS = {"name", "kind", "frame_a", "offset_a", "frame_b", "offset_b", "stiffness", "damping", "rest_length"}
FORCE_KINDS = ("joint-torque", "spring-damper")
INITIAL_KEYS = {"q", "v"}


@dataclass(frozen=True)
class ClosureSpec:
    """A loop closure as declared in the scene (frames by name, offsets in those frames)."""

    name: str
    kind: str
    frame_a: str
    placement_a: pin.SE3
    frame_b: str  # "world" for a fixed world placement
    placement_b: pin.SE3
    plane: str | tuple[float, float, float] = "xy"


@dataclass
class Scene:
    """Everything a simulation needs.

    Attributes:
        name: scene name.
        model: the (reduced) Pinocchio model, with an operational frame at every closure and
            spring point.
        constraints: all constraint blocks (closures first, then user-added ones).
        forces: force elements.
        q0, v0: initial configuration and velocity as declared (before assembly).
        closures: the closure declarations.
        urdf_path: URDF file (None for generated robots); package_dirs: where meshes are found.
        locked_joints: joints removed from the model, with the positions they were locked at.
        parameters: generator parameters the scene was built with.
    """

    name: str
    description: str
    model: pin.Model
    constraints: list[Constraint]
    forces: list[ForceElement]
    q0: np.ndarray
    v0: np.ndarray
    closures: list[ClosureSpec]
    urdf_path: Path | None = None
    urdf_text: str | None = None
    package_dirs: list[str] = field(default_factory=list)
    locked_joints: dict[str, float] = field(default_factory=dict)
    full_model: pin.Model | None = None
    source: Path | None = None
    parameters: dict[str, Any] = field(default_factory=dict)

    @property
    def constraint_set(self) -> ConstraintSet:
        """The constraint blocks stacked into rows."""
        return ConstraintSet(self.constraints, self.model.nv)

    def add_constraint(self, constraint: Constraint) -> None:
        """Add a user-defined constraint block (see :mod:`pinstab.constraints.custom`)."""
        if constraint.name in {c.name for c in self.constraints}:
            raise SceneError(f"constraint name {constraint.name!r} is already used in scene {self.name}")
        self.constraints.append(constraint)

    def frame_id(self, name: str) -> int:
        """Index of a frame of the model; SceneError listing the frames otherwise."""
        return _frame_id(self.model, name, "frame")

    def joint_velocity_index(self, joint: str) -> int:
        """Index of a joint's first velocity coordinate."""
        return self.model.joints[_joint_id(self.model, joint, "joint")].idx_v


def load_scene(path_or_name: str | Path, **parameters: Any) -> Scene:
    """Read a scene from a TOML file or a bundled scene name.

    Args:
        path_or_name: a path to a ``.toml`` scene file, or a bundled scene name (``fourbar``, ...).
        parameters: generator parameters overriding the scene file's (e.g. ``N=20`` for
            ``nfourbar``).

    Raises:
        SceneError: unknown scene, key, frame or joint, wrong type or unit; the message names the
            item and lists the valid alternatives.
    """
    path = _locate(path_or_name)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"scene file {path}: not valid TOML: {exc}") from None
    except OSError as exc:
        raise SceneError(f"scene file {path}: cannot be read: {exc.strerror}") from None
    return scene_from_dict(data, name=path.stem, base_dir=path.parent, parameters=parameters, source=path)


def _locate(path_or_name: str | Path) -> Path:
    candidate = Path(path_or_name)
    if candidate.suffix == ".toml" or candidate.is_file():
        if not candidate.is_file():
            raise SceneError(f"scene file {candidate} does not exist")
        return candidate
    bundled = robots.bundled_scenes()
    if str(path_or_name) in bundled:
        return bundled[str(path_or_name)]
    raise SceneError(
        f"no scene named {str(path_or_name)!r}: it is neither a bundled scene nor a .toml file. "
        f"Bundled scenes: {choices(bundled)}. Pass a path to a scene file to use your own."
    )


def scene_from_dict(
    data: dict[str, Any],
    name: str = "scene",
    base_dir: Path | None = None,
    parameters: dict[str, Any] | None = None,
    source: Path | None = None,
) -> Scene:
    """Build a :class:`Scene` from parsed scene-file content (see :func:`load_scene`)."""
    data = copy.deepcopy(data)
    base_dir = base_dir or Path.cwd()
    _check_keys(data, TOP_KEYS, "scene")
    used_parameters: dict[str, Any] = {}
    if "generator" in data:
        generator = _table(data.pop("generator"), "generator")
        gen_name = generator.pop("name", None)
        if not isinstance(gen_name, str):
            raise SceneError("generator: the 'name' key (a string) is required")
        used_parameters = {**generator, **(parameters or {})}
        generated = generate(gen_name, used_parameters)
        for key, value in generated.items():
            data.setdefault(key, value)
    elif parameters:
        raise SceneError(
            f"scene {name}: parameters {choices(parameters)} given, but the scene has no [generator] to take them"
        )
    name = str(data.get("name", name))
    description = str(data.get("description", ""))

    robot = _table(data.get("robot"), "robot")
    _check_keys(robot, ROBOT_KEYS, "robot")
    full_model, urdf_path, urdf_text, package_dirs = _build_model(robot, base_dir)

    initial = _table(data.get("initial", {}), "initial")
    _check_keys(initial, INITIAL_KEYS, "initial")
    q_table = _table(initial.get("q", {}), "initial.q")
    v_table = _table(initial.get("v", {}), "initial.v")
    q_full = _configuration(full_model, q_table)

    locked = robot.get("locked_joints", [])
    if not isinstance(locked, list) or not all(isinstance(j, str) for j in locked):
        raise SceneError("robot.locked_joints must be a list of joint names")
    locked_ids = [_joint_id(full_model, j, "robot.locked_joints") for j in locked]
    if locked_ids:
        model = pin.buildReducedModel(full_model, locked_ids, q_full)
    else:
        model = full_model.copy()
    locked_positions = {j: float(q_full[full_model.joints[_joint_id(full_model, j, "robot")].idx_q]) for j in locked}
    model.gravity = pin.Motion(
        _vector(data.get("gravity", [0.0, 0.0, -9.81]), 3, "gravity", "acceleration"), np.zeros(3)
    )

    for j in list(q_table):
        if j in locked:
            q_table.pop(j)
    for j in v_table:
        if j in locked:
            raise SceneError(f"initial.v: joint {j!r} is locked (robot.locked_joints); it cannot move")
    q0 = _configuration(model, q_table)
    v0 = _velocity(model, v_table)

    closure_tables = _list_of_tables(data.get("closures", []), "closures")
    force_tables = _list_of_tables(data.get("forces", []), "forces")
    closures = [_closure_spec(t, i) for i, t in enumerate(closure_tables)]
    _check_unique([c.name for c in closures] + [str(t.get("name", f"force{i}")) for i, t in enumerate(force_tables)])
    constraints: list[Constraint] = [_closure(model, spec) for spec in closures]
    forces = [_force(model, t, i) for i, t in enumerate(force_tables)]
    return Scene(
        name=name,
        description=description,
        model=model,
        constraints=constraints,
        forces=forces,
        q0=q0,
        v0=v0,
        closures=closures,
        urdf_path=urdf_path,
        urdf_text=urdf_text,
        package_dirs=package_dirs,
        locked_joints=locked_positions,
        full_model=full_model,
        source=source,
        parameters=used_parameters,
    )


# -- robot --------------------------------------------------------------------------------------
def _build_model(robot: dict[str, Any], base_dir: Path) -> tuple[pin.Model, Path | None, str | None, list[str]]:
    sources = [k for k in ("urdf", "name", "urdf_text") if k in robot]
    if len(sources) != 1:
        raise SceneError("robot: give exactly one of 'urdf' (a URDF path) or 'name' (an example-robot-data robot)")
    free_flyer = robot.get("free_flyer", False)
    if not isinstance(free_flyer, bool):
        raise SceneError(f"robot.free_flyer must be true or false, got {free_flyer!r}")
    root = [pin.JointModelFreeFlyer()] if free_flyer else []
    urdf_path: Path | None = None
    urdf_text: str | None = None
    package_dirs: list[str] = []
    if "urdf_text" in robot:
        urdf_text = str(robot["urdf_text"])
    elif "name" in robot:
        if not isinstance(robot["name"], str):
            raise SceneError("robot.name must be a string")
        urdf_path, package_dir = robots.example_robot_urdf(robot["name"])
        # meshes are named package://example-robot-data/robots/...: the share/ folder resolves them
        package_dirs = [str(package_dir), str(package_dir.parent), str(package_dir.parent.parent)]
    else:
        if not isinstance(robot["urdf"], str):
            raise SceneError("robot.urdf must be a path string")
        urdf_path = (base_dir / robot["urdf"]).resolve()
        if not urdf_path.is_file():
            raise SceneError(f"robot.urdf: file {urdf_path} does not exist")
        package_dirs = [str(urdf_path.parent)]
    try:
        if urdf_text is not None:
            model = pin.buildModelFromXML(urdf_text, *root)
        else:
            model = pin.buildModelFromUrdf(str(urdf_path), *root)
    except (ValueError, RuntimeError) as exc:
        raise SceneError(f"robot: the URDF cannot be read: {exc}") from None
    return model, urdf_path, urdf_text, package_dirs


def _joint_id(model: pin.Model, name: str, where: str) -> int:
    if not isinstance(name, str) or not model.existJointName(name) or name == "universe":
        valid = [n for n in model.names if n != "universe"]
        raise SceneError(f"{where}: unknown joint {name!r}; valid joints: {choices(valid)}")
    return model.getJointId(name)


FRAME_PREFERENCE = (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT, pin.FrameType.JOINT)


def _frame_id(model: pin.Model, name: str, where: str) -> int:
    """Frame index by name; a link (BODY) frame wins over a joint frame of the same name."""
    if isinstance(name, str):
        for frame_type in FRAME_PREFERENCE:
            if model.existFrame(name, frame_type):
                return model.getFrameId(name, frame_type)
    valid = [f.name for f in model.frames if f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)]
    raise SceneError(f"{where}: unknown frame {name!r}; valid frames: {WORLD}, {choices(valid)}")


def _joint_kind(model: pin.Model, joint_id: int) -> str:
    short = model.joints[joint_id].shortname()
    if short.startswith("JointModelR"):
        return "angle"
    if short.startswith("JointModelP"):
        return "length"
    return "other"


def _configuration(model: pin.Model, table: dict[str, Any]) -> np.ndarray:
    q = pin.neutral(model)
    for joint, value in table.items():
        jid = _joint_id(model, joint, "initial.q")
        jm = model.joints[jid]
        kind = _joint_kind(model, jid)
        where = f"initial.q.{joint}"
        if kind != "other" and jm.nq in (1, 2) and jm.nv == 1:
            x = quantity(value, kind, where)
            q[jm.idx_q : jm.idx_q + jm.nq] = [x] if jm.nq == 1 else [np.cos(x), np.sin(x)]
        else:
            q[jm.idx_q : jm.idx_q + jm.nq] = _vector(value, jm.nq, where, None)
    return q


def _velocity(model: pin.Model, table: dict[str, Any]) -> np.ndarray:
    v = np.zeros(model.nv)
    for joint, value in table.items():
        jid = _joint_id(model, joint, "initial.v")
        jm = model.joints[jid]
        kind = _joint_kind(model, jid)
        where = f"initial.v.{joint}"
        if kind != "other" and jm.nv == 1:
            v[jm.idx_v] = quantity(value, "angular-velocity" if kind == "angle" else "velocity", where)
        else:
            v[jm.idx_v : jm.idx_v + jm.nv] = _vector(value, jm.nv, where, None)
    return v


# -- closures and forces ---------------------------------------------------------------------
def _placement(table: dict[str, Any], offset_key: str, rpy_key: str, where: str) -> pin.SE3:
    offset = _vector(table.get(offset_key, [0.0, 0.0, 0.0]), 3, f"{where}.{offset_key}", "length")
    rpy = _vector(table.get(rpy_key, [0.0, 0.0, 0.0]), 3, f"{where}.{rpy_key}", "angle")
    return pin.SE3(pin.rpy.rpyToMatrix(rpy), offset)


def _closure_spec(table: dict[str, Any], index: int) -> ClosureSpec:
    where = f"closures[{index}]"
    _check_keys(table, CLOSURE_KEYS, where)
    name = table.get("name", f"closure{index}")
    if not isinstance(name, str):
        raise SceneError(f"{where}.name must be a string")
    where = f"closure {name!r}"
    kind = table.get("kind")
    if kind not in CLOSURE_KINDS:
        raise SceneError(f"{where}: kind {kind!r} is not a closure kind; valid kinds: {choices(CLOSURE_KINDS)}")
    if "frame_a" not in table:
        raise SceneError(f"{where}: 'frame_a' is required")
    plane: str | tuple[float, float, float] = "xy"
    if kind == "planar-point":
        raw = table.get("plane")
        if isinstance(raw, str) and raw in PLANES:
            plane = raw
        elif isinstance(raw, list):
            plane = tuple(_vector(raw, 3, f"{where}.plane", None))  # type: ignore[assignment]
        else:
            raise SceneError(f"{where}: 'plane' must be one of {choices(PLANES)} or a normal vector, got {raw!r}")
    elif "plane" in table:
        raise SceneError(f"{where}: 'plane' only applies to kind 'planar-point'")
    return ClosureSpec(
        name=name,
        kind=kind,
        frame_a=table["frame_a"],
        placement_a=_placement(table, "offset_a", "rpy_a", where),
        frame_b=table.get("frame_b", WORLD),
        placement_b=_placement(table, "offset_b", "rpy_b", where),
        plane=plane,
    )


def _add_point_frame(model: pin.Model, frame_name: str, placement: pin.SE3, new_name: str, where: str) -> int:
    parent = _frame_id(model, frame_name, where)
    frame = model.frames[parent]
    return model.addFrame(
        pin.Frame(new_name, frame.parentJoint, parent, frame.placement * placement, pin.FrameType.OP_FRAME)
    )


def _closure(model: pin.Model, spec: ClosureSpec) -> FrameClosure:
    where = f"closure {spec.name!r}"
    frame_a = _add_point_frame(model, spec.frame_a, spec.placement_a, f"{spec.name}/a", f"{where}.frame_a")
    if spec.frame_b == WORLD:
        return FrameClosure(spec.name, spec.kind, frame_a, None, spec.placement_b, spec.plane)
    frame_b = _add_point_frame(model, spec.frame_b, spec.placement_b, f"{spec.name}/b", f"{where}.frame_b")
    return FrameClosure(spec.name, spec.kind, frame_a, frame_b, None, spec.plane)


def _force(model: pin.Model, table: dict[str, Any], index: int) -> ForceElement:
    where = f"forces[{index}]"
    kind = table.get("kind")
    if kind not in FORCE_KINDS:
        raise SceneError(f"{where}: kind {kind!r} is not a force kind; valid kinds: {choices(FORCE_KINDS)}")
    name = str(table.get("name", f"force{index}"))
    where = f"force {name!r}"
    if kind == "joint-torque":
        _check_keys(table, TORQUE_KEYS, where)
        jid = _joint_id(model, table.get("joint"), f"{where}.joint")
        jm = model.joints[jid]
        if jm.nv != 1:
            raise SceneError(f"{where}: joint {table['joint']!r} has {jm.nv} DOF; joint torques need a 1-DOF joint")
        if ("torque" in table) == ("table" in table):
            raise SceneError(f"{where}: give exactly one of 'torque' (constant) or 'table' ([[t, torque], ...])")
        if "torque" in table:
            times, values = np.zeros(1), np.array([quantity(table["torque"], "torque", f"{where}.torque")])
        else:
            rows = table["table"]
            if not isinstance(rows, list) or not rows or not all(isinstance(r, list) and len(r) == 2 for r in rows):
                raise SceneError(f"{where}.table must be a non-empty list of [time, torque] pairs")
            times = np.array([quantity(r[0], "time", f"{where}.table time") for r in rows])
            values = np.array([quantity(r[1], "torque", f"{where}.table torque") for r in rows])
            if np.any(np.diff(times) <= 0):
                raise SceneError(f"{where}.table: times must be strictly increasing")
        return JointTorque(name, jm.idx_v, model.nv, times, values)
    _check_keys(table, SPRING_KEYS, where)
    if "frame_a" not in table:
        raise SceneError(f"{where}: 'frame_a' is required")
    placement_a = _placement(table, "offset_a", "rpy_a", where)
    frame_a = _add_point_frame(model, table["frame_a"], placement_a, f"{name}/a", f"{where}.frame_a")
    frame_b_name = table.get("frame_b", WORLD)
    offset_b = _vector(table.get("offset_b", [0.0, 0.0, 0.0]), 3, f"{where}.offset_b", "length")
    frame_b = None
    if frame_b_name != WORLD:
        frame_b = _add_point_frame(model, frame_b_name, pin.SE3(np.eye(3), offset_b), f"{name}/b", f"{where}.frame_b")
    stiffness = quantity(table.get("stiffness", 0.0), "stiffness", f"{where}.stiffness")
    damping = quantity(table.get("damping", 0.0), "damping", f"{where}.damping")
    rest = quantity(table.get("rest_length", 0.0), "length", f"{where}.rest_length")
    for label, value in (("stiffness", stiffness), ("damping", damping), ("rest_length", rest)):
        if value < 0:
            raise SceneError(f"{where}.{label} must be >= 0, got {value}")
    return SpringDamper(name, frame_a, frame_b, offset_b, stiffness, damping, rest)


# -- small validators ---------------------------------------------------------------------------
def _check_unique(names: list[str]) -> None:
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise SceneError(f"closure and force names must be unique; repeated: {', '.join(repeated)}")


def _check_keys(table: dict[str, Any], allowed: set[str], where: str) -> None:
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise SceneError(f"{where}: unknown key {unknown[0]!r}; valid keys: {choices(allowed)}")


def _table(value: Any, where: str) -> dict[str, Any]:
    if value is None:
        raise SceneError(f"scene: the [{where}] table is required")
    if not isinstance(value, dict):
        raise SceneError(f"{where} must be a table, got {type(value).__name__}")
    return value


def _list_of_tables(value: Any, where: str) -> list[dict[str, Any]]:
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise SceneError(f"{where} must be an array of tables ([[{where}]])")
    return value


def _vector(value: Any, size: int, where: str, dimension: str | None) -> np.ndarray:
    if not isinstance(value, list) or len(value) != size:
        raise SceneError(f"{where} must be a list of {size} numbers, got {value!r}")
    if dimension is None:
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
            raise SceneError(f"{where} must be a list of {size} numbers, got {value!r}")
        out = np.array(value, dtype=float)
        if not np.all(np.isfinite(out)):
            raise SceneError(f"{where} has a non-finite entry")
        return out
    return np.array([quantity(x, dimension, where) for x in value])


__all__ = ["ClosureSpec", "Scene", "load_scene", "scene_from_dict"]
