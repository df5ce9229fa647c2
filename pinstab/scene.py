"""Scenes: a robot (reduced to what the scene needs), loop closures, force elements, initial state.

A scene is read from a TOML file (or a bundled scene by name) by :func:`load_scene`. Scene files
are data: nothing in them is evaluated. See ``robots/*.toml`` for examples and README for the
schema.
"""

from __future__ import annotations

import copy
import functools
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from .actuation import Actuation, read_actuation
from .constraints import CONSTRAINT_KINDS, Constraint, ConstraintSet
from .contact.collisions import CollisionCheck, edge_contacts
from .contact.objects import SceneObject, add_objects, place_objects
from .errors import PinstabWarning, SceneError, choices, repeated
from .forces import FORCE_KINDS, ForceElement
from .generators import generate
from .kernels import tilted_gravity
from .memory import named_when_exhausted
from .readers import READERS, ROBOT_KEYS, RobotSource, bundled_scenes, read_robot
from .readers.base import reduce_model, robot_geometry, robot_start
from .readers.urdf import read_body
from .registry import Registry
from .tables import SceneTables, check_keys, frame_id, joint_id, list_of_tables, table, vector
from .units import quantity
from .validation import (
    check_closures,
    check_configuration,
    check_depth,
    check_locked_joints,
    check_model,
    check_velocity,
    read_scene_file,
    relative_tolerance,
)

MAX_GRAVITY = 1e6  # [m/s^2]
CONTACT_TREATMENTS = ("held", "event", "stepping")  # [run] contacts: rows that hold, event-driven, time-stepping
TOP_KEYS = {
    "name",
    "description",
    "robot",
    "generator",
    "gravity",
    "tilt",
    "objects",
    "closures",
    "contacts",
    "forces",
    "servos",
    "actuation",
    "initial",
    "assembly",
    "run",
}
INITIAL_KEYS = {"q", "v"}
RUN_KEYS = {"dt", "contacts", "rtol"}
# scene arrays read through a registry: each entry's 'kind' picks the reader
KIND_TABLES = {  # scene array: (what an entry is called, whether its blocks are prescribed)
    "closures": ("closure", False),
    "contacts": ("contact", False),
    "servos": ("servo", True),  # prescribed constraints: realized by the controls (docs/mathematics.md 5)
}


@dataclass
class Scene:
    """Everything a simulation needs.

    Attributes:
        name: scene name.
        model: the (reduced) Pinocchio model, with an operational frame at every closure and
            spring point.
        constraints: all constraint blocks (closures, then contacts, then user-added ones).
        forces: force elements.
        q0, v0: initial configuration and velocity as declared (before assembly).
        urdf_path: URDF file (None for generated robots); package_dirs: where meshes are found.
        locked_joints: joints removed from the model, with the positions they were locked at.
        parameters: generator parameters the scene was built with. generator: the generator's name, or None.
        objects: rigid objects added to the robot (free-flyer bodies after its joints).
        actuation: the controls' matrix B, names and limits (``[actuation]``), or None.
        tilt: gravity turning in time (``[tilt]``), or None. robot: the robot as its reader built it.
        assembly_tolerance: ``[assembly] tolerance``, the residual assembly accepts relative to the mechanism's
            size [-] (:func:`~pinstab.assembly.assemble`), or None (the default).
        step: ``[run] dt``, the scene's time step [s] (what ``simulate`` and ``--dt`` default to), or None (1e-3).
        contacts: ``[run] contacts``, the contact treatment the scene asks for (:data:`CONTACT_TREATMENTS`; what
            ``--contacts`` defaults to), or None (:func:`~pinstab.simulate.choice.contact_choice`).
        rtol: ``[run] rtol``, the relative tolerance of its event-driven runs (what ``rtol`` and ``--rtol`` default to
            with ``contacts="event"``), or None (1e-10).
        collisions: the robot-object collision checks of a scene with objects
            (:mod:`pinstab.contact.collisions`: warned at load, run at a run's samples), or None.
        contact_finders: the finders of its contacts from geometry
            (:class:`~pinstab.constraints.geometry_contacts.FoundContacts`), which event-driven runs ask at every step.
    """

    name: str
    description: str
    model: pin.Model
    constraints: list[Constraint]
    forces: list[ForceElement]
    q0: np.ndarray
    v0: np.ndarray
    urdf_path: Path | None = None
    urdf_text: str | None = None
    package_dirs: list[str] = field(default_factory=list)
    locked_joints: dict[str, float] = field(default_factory=dict)
    full_model: pin.Model | None = None
    source: Path | None = None
    parameters: dict[str, Any] = field(default_factory=dict)
    generator: str | None = None
    objects: list[SceneObject] = field(default_factory=list)
    actuation: Actuation | None = None
    tilt: GravityTilt | None = None
    robot: RobotSource | None = None
    assembly_tolerance: float | None = None
    step: float | None = None
    contacts: str | None = None
    rtol: float | None = None
    collisions: CollisionCheck | None = None
    contact_finders: list[Any] = field(default_factory=list)

    @property
    def constraint_set(self) -> ConstraintSet:
        """The constraint blocks stacked into rows."""
        return ConstraintSet(self.constraints, self.model.nv)

    def add_constraint(self, constraint: Constraint) -> None:
        """Add a user-defined constraint block (see :mod:`pinstab.constraints.custom`)."""
        if constraint.name in {c.name for c in self.constraints}:
            raise SceneError(f"constraint name {constraint.name!r} is already used in scene {self.name}")
        self.constraints.append(constraint)

    def add_servo(self, constraint: Constraint, actuation: Actuation | None = None) -> None:
        """Add a user-defined constraint block as a prescribed constraint (a servo: the controls realize it,
        its reaction is zero), with the scene's actuation or ``actuation`` (which replaces it)."""
        if actuation is not None:
            self.actuation = actuation
        if self.actuation is None:
            raise SceneError(f"servo {constraint.name!r}: the scene has no actuation; pass one (pinstab.Actuation)")
        constraint.prescribed = True
        self.add_constraint(constraint)

    def frame_id(self, name: str) -> int:
        """Index of a frame of the model; SceneError listing the frames otherwise."""
        return frame_id(self.model, name, "frame")

    def joint_velocity_index(self, joint: str) -> int:
        """Index of a joint's first velocity coordinate."""
        return self.model.joints[joint_id(self.model, joint, "joint")].idx_v


@named_when_exhausted("loading a scene (load_scene)")
def load_scene(path_or_name: str | Path, keyframe: str | None = None, **parameters: Any) -> Scene:
    """Read a scene from a TOML file or a bundled scene name.

    Args:
        path_or_name: a path to a ``.toml`` scene file, or a bundled scene name (``fourbar``, ...).
        keyframe: the robot file's keyframe to start from (an MJCF ``<key>`` by name; ``robot.keyframe`` of the
            scene); None: the scene's, else the file's first.
        parameters: generator parameters overriding the scene file's (e.g. ``N=20`` for
            ``nfourbar``).

    Raises:
        SceneError: unknown scene, key, frame or joint, wrong type or unit; the message names the
            item and lists the valid alternatives.
    """
    path = _locate(path_or_name)
    data = read_scene_file(path)
    return scene_from_dict(
        data, name=path.stem, base_dir=path.parent, parameters=parameters, source=path, keyframe=keyframe
    )


def _locate(path_or_name: str | Path) -> Path:
    candidate = Path(path_or_name)
    if candidate.suffix == ".toml" or candidate.is_file():
        if not candidate.is_file():
            raise SceneError(f"scene file {candidate} does not exist")
        return candidate
    bundled = bundled_scenes()
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
    keyframe: str | None = None,
) -> Scene:
    """Build a :class:`Scene` from parsed scene-file content (see :func:`load_scene`)."""
    check_depth(data, f"scene file {source}" if source else f"scene {name}")
    data = copy.deepcopy(data)
    base_dir = base_dir or Path.cwd()
    check_keys(data, TOP_KEYS, "scene")
    used_parameters: dict[str, Any] = {}
    gen_name = None
    if "generator" in data:
        generator = table(data.pop("generator"), "generator")
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

    robot = table(data.get("robot"), "robot") | ({} if keyframe is None else {"keyframe": keyframe})
    check_keys(robot, ROBOT_KEYS | set(READERS), "robot")
    source_robot = read_robot(robot, base_dir)
    full_model = source_robot.model
    _ignore_limits(full_model, robot.get("ignore_limits", []))
    locked = robot.get("locked_joints", [])
    for key, entries in source_robot.tables.items():  # the file's closures, relations, springs before the scene's
        moving = [entry for entry in entries if not (isinstance(locked, list) and entry.get("joint") in locked)]
        data[key] = moving + list_of_tables(data.get(key, []), key)

    initial = table(data.get("initial", {}), "initial")
    check_keys(initial, INITIAL_KEYS, "initial")
    q_table = table(initial.get("q", {}), "initial.q")
    v_table = table(initial.get("v", {}), "initial.v")
    start = robot_start(source_robot, full_model)[0]
    q_full = _configuration(full_model, {j: x for j, x in q_table.items() if full_model.existJointName(j)}, start)
    check_configuration(full_model, q_full, "initial.q")

    if not isinstance(locked, list) or not all(isinstance(j, str) for j in locked):
        raise SceneError("robot.locked_joints must be a list of joint names")
    check_locked_joints(locked)
    locked_ids = [joint_id(full_model, j, "robot.locked_joints") for j in locked]
    if locked_ids:
        model = reduce_model(full_model, locked_ids, q_full)[0]
    else:
        model = full_model.copy()
    locked_positions = {j: float(q_full[full_model.joints[joint_id(full_model, j, "robot")].idx_q]) for j in locked}
    model.gravity = pin.Motion(_gravity(data.get("gravity", [0.0, 0.0, -9.81])), np.zeros(3))

    objects = add_objects(model, data.get("objects", []), functools.partial(read_body, base_dir=base_dir))
    for j in list(q_table):
        if j in locked:
            q_table.pop(j)
    for j in v_table:
        if j in locked:
            raise SceneError(f"initial.v: joint {j!r} is locked (robot.locked_joints); it cannot move")
    start, start_v = robot_start(source_robot, model)
    q0 = _configuration(model, q_table, start)
    check_configuration(model, q0, "initial.q")
    place_objects(objects, q0, set(q_table))
    check_model(model)
    v0 = _velocity(model, v_table, start_v)
    check_velocity(model, v0, "initial.v")

    tables = SceneTables(model, q0, {item.name: item for item in objects})
    tables.robot_shapes = _robot_shapes(source_robot, locked_positions)
    constraints: list[Constraint] = []
    for key, (label, prescribed) in KIND_TABLES.items():
        blocks = _read_kinds(data, key, label, CONSTRAINT_KINDS, tables)
        for block in blocks if prescribed else ():
            block.prescribed = True
        constraints += blocks
    actuation = read_actuation(data.get("actuation"), model)
    if any(c.prescribed for c in constraints) and actuation is None:
        raise SceneError("scene: [[servos]] need controls to realize them: add an [actuation] table (joints or matrix)")
    check_closures(model, constraints)
    tables.constraints = {c.name: c for c in constraints}
    forces: list[ForceElement] = _read_kinds(data, "forces", "force", FORCE_KINDS, tables)
    _check_unique([c.name for c in constraints] + [f.name for f in forces])
    collisions = _collisions(name, model, q0, tables.robot_shapes, objects, constraints)
    return Scene(
        name=name,
        description=description,
        model=model,
        constraints=constraints,
        forces=forces,
        q0=q0,
        v0=v0,
        urdf_path=source_robot.urdf_path,
        urdf_text=source_robot.urdf_text,
        package_dirs=source_robot.package_dirs,
        robot=source_robot,
        locked_joints=locked_positions,
        full_model=full_model,
        source=source,
        parameters=used_parameters,
        generator=gen_name,
        objects=objects,
        actuation=actuation,
        tilt=None if "tilt" not in data else _tilt(data["tilt"], model.gravity.linear),
        assembly_tolerance=_assembly_tolerance(data.get("assembly")),
        step=_run_step(data.get("run")),
        contacts=_run_contacts(data.get("run")),
        rtol=_run_tolerance(data.get("run")),
        collisions=collisions,
        contact_finders=tables.contact_finders,
    )


@dataclass(frozen=True)
class GravityTilt:
    """The robot's base turned by ``start`` [rad] and turning at ``rate`` [rad/s] about the world ``axis``
    (unit), modelled by gravity turning the other way: ``g(t) = R(axis, -(start + rate t)) g0`` [m/s^2] (the
    slow turn's own accelerations, omega^2 r and 2 omega x v, are left out), until the turn reaches ``stop`` [rad]
    (inf: it turns on), from when on gravity stays. Scene table ``[tilt]``: ``axis``, ``rate`` (e.g.
    ``"2 deg/s"``), optional ``start`` (e.g. ``"1.5 deg"``) and ``stop`` (e.g. ``"2 deg"``)."""

    axis: np.ndarray
    rate: float
    gravity0: np.ndarray
    start: float = 0.0
    stop: float = math.inf

    def gravity(self, t: float) -> np.ndarray:
        """Gravity at time t [s], in world axes [m/s^2]."""
        return tilted_gravity(self.axis, self.rate, self.start, self.gravity0, t, self.stop)

    def compiled_form(self) -> dict[str, Any]:
        """The tilt as the core kernel takes it (``cpp/core_kernel.hpp`` GravityTilt)."""
        return {
            "axis": self.axis,
            "gravity0": self.gravity0,
            "rate": float(self.rate),
            "start": float(self.start),
            "stop": float(self.stop),
        }


def _tilt(value: Any, gravity: np.ndarray) -> GravityTilt:
    keys = {"axis", "rate", "start", "stop"}
    if not isinstance(value, dict) or not {"axis", "rate"} <= set(value) <= keys:
        raise SceneError(
            "tilt must be a table with 'axis' (a world direction), 'rate' (e.g. '2 deg/s') and optionally 'start' "
            f"(e.g. '1.5 deg') and 'stop' (e.g. '2 deg'), got {value!r}"
        )
    axis = vector(value["axis"], 3, "tilt.axis", None)
    if not np.linalg.norm(axis) > 1e-12:
        raise SceneError(f"tilt.axis must be a non-zero vector, got {value['axis']!r}")
    rate = quantity(value["rate"], "angular-velocity", "tilt.rate")
    start = quantity(value.get("start", 0.0), "angle", "tilt.start")
    stop = math.inf
    if "stop" in value:
        stop = quantity(value["stop"], "angle", "tilt.stop")
        if not (stop - start) * rate > 0.0:
            raise SceneError(
                f"tilt.stop must be an angle the turn reaches from start ({start:.6g} rad) at rate {rate:.6g} rad/s, "
                f"got {value['stop']!r}"
            )
    return GravityTilt(axis / np.linalg.norm(axis), rate, gravity.copy(), start, stop)


def _robot_shapes(robot: RobotSource, locked: dict[str, float]) -> Callable[[], pin.GeometryModel]:
    """The robot's collision geometry, reduced like the scene's model, built once when first called.

    Raises (when called):
        SceneError: its reader cannot build it (a mesh missing, ...).
    """

    @functools.cache
    def shapes() -> pin.GeometryModel:
        try:
            return robot_geometry(robot, robot.model, locked, pin.GeometryType.COLLISION)
        except (ValueError, RuntimeError) as exc:
            raise SceneError(f"the robot's collision geometry cannot be loaded ({exc})") from None

    return shapes


def _collisions(
    name: str,
    model: pin.Model,
    q0: np.ndarray,
    robot_shapes: Callable[[], pin.GeometryModel],
    objects: list[SceneObject],
    constraints: list[Constraint],
) -> CollisionCheck | None:
    """The robot-object collision checks of a scene with objects, after warning of overlaps and of contacts on
    edges at the start (:mod:`pinstab.contact.collisions`); None without objects."""
    if not objects:
        return None
    touches = [c.touch for c in constraints if c.touch is not None]
    try:
        geometry = robot_shapes()
    except SceneError as exc:
        warnings.warn(PinstabWarning(f"scene {name}: {exc}; not checked"), stacklevel=3)
        geometry = pin.GeometryModel()
    check = CollisionCheck(model, geometry, objects, touches)
    check.warn_at_start(q0, name)
    edge_contacts(model, q0, objects, touches, name)
    return check


def _ignore_limits(model: pin.Model, joints: Any) -> None:
    """``robot.ignore_limits``: the joints whose limits the scene sets aside (their bounds made infinite), or
    ``true`` for every joint (as ``--ignore-limits`` does for one run)."""
    where = "robot.ignore_limits"
    if joints is True:
        joints = list(model.names[1:])
    if not isinstance(joints, list):
        raise SceneError(f"{where} must be a list of joint names or true (every joint), got {joints!r}")
    lower, upper = model.lowerPositionLimit.copy(), model.upperPositionLimit.copy()
    for name in joints:
        joint = model.joints[joint_id(model, name, where)]
        lower[joint.idx_q : joint.idx_q + joint.nq] = -np.inf
        upper[joint.idx_q : joint.idx_q + joint.nq] = np.inf
    model.lowerPositionLimit, model.upperPositionLimit = lower, upper


def _run_contacts(value: Any) -> str | None:
    """``[run] contacts``, the treatment the scene asks for (:data:`CONTACT_TREATMENTS`), or None when not given."""
    if value is None or "contacts" not in table(value, "run"):
        return None
    if value["contacts"] not in CONTACT_TREATMENTS:
        raise SceneError(
            f"run.contacts: unknown treatment {value['contacts']!r}; valid: {', '.join(CONTACT_TREATMENTS)}"
        )
    return value["contacts"]


def _run_step(value: Any) -> float | None:
    """``[run] dt``, the scene's time step [s] (positive, finite; units allowed), or None when not given."""
    if value is None:
        return None
    check_keys(table(value, "run"), RUN_KEYS, "run")
    if "dt" not in value:
        return None
    step = quantity(value["dt"], "time", "run.dt")
    if not 0.0 < step < math.inf:
        raise SceneError(f"run.dt must be a positive time step, e.g. 5e-4 or '0.5 ms', got {value['dt']!r}")
    return step


def _run_tolerance(value: Any) -> float | None:
    """``[run] rtol``, the relative tolerance [-] of the scene's error-controlled runs (event-driven contacts), in
    (0, 1), or None when not given."""
    if value is None or "rtol" not in value:
        return None
    return relative_tolerance(value["rtol"], "run.rtol", "of the error control's step")


def _assembly_tolerance(value: Any) -> float | None:
    """``[assembly] tolerance`` (relative, in (0, 1)), or None when the table is absent."""
    if value is None:
        return None
    check_keys(table(value, "assembly"), {"tolerance"}, "assembly")
    return None if "tolerance" not in value else relative_tolerance(value["tolerance"], "assembly.tolerance")


# -- robot --------------------------------------------------------------------------------------
def _gravity(value: Any) -> np.ndarray:
    """The gravity vector [m/s^2], at most :data:`MAX_GRAVITY` long (beyond, the dynamics overflow)."""
    gravity = vector(value, 3, "gravity", "acceleration")
    if np.max(np.abs(gravity)) > MAX_GRAVITY or np.linalg.norm(gravity) > MAX_GRAVITY:  # no overflow warning
        raise SceneError(
            f"gravity {gravity.tolist()} m/s^2 is longer than {MAX_GRAVITY:g} m/s^2 (1e5 g); give it in m/s^2"
        )
    return gravity


def _joint_kind(model: pin.Model, joint_id: int) -> str:
    short = model.joints[joint_id].shortname()
    if short.startswith("JointModelR"):
        return "angle"
    if short.startswith("JointModelP"):
        return "length"
    return "other"


def _configuration(model: pin.Model, table: dict[str, Any], start: np.ndarray) -> np.ndarray:
    """``start`` [rad, m] with the joints of ``table`` (``initial.q``) set."""
    q = start.copy()
    for joint, value in table.items():
        jid = joint_id(model, joint, "initial.q")
        jm = model.joints[jid]
        kind = _joint_kind(model, jid)
        where = f"initial.q.{joint}"
        if kind != "other" and jm.nq in (1, 2) and jm.nv == 1:
            x = quantity(value, kind, where)
            q[jm.idx_q : jm.idx_q + jm.nq] = [x] if jm.nq == 1 else [np.cos(x), np.sin(x)]
        else:
            q[jm.idx_q : jm.idx_q + jm.nq] = vector(value, jm.nq, where, None)
    return q


def _velocity(model: pin.Model, table: dict[str, Any], start: np.ndarray) -> np.ndarray:
    """``start`` [rad/s, m/s] with the joints of ``table`` (``initial.v``) set."""
    v = start.copy()
    for joint, value in table.items():
        jid = joint_id(model, joint, "initial.v")
        jm = model.joints[jid]
        kind = _joint_kind(model, jid)
        where = f"initial.v.{joint}"
        if kind != "other" and jm.nv == 1:
            v[jm.idx_v] = quantity(value, "angular-velocity" if kind == "angle" else "velocity", where)
        else:
            v[jm.idx_v : jm.idx_v + jm.nv] = vector(value, jm.nv, where, None)
    return v


# -- constraints and forces ----------------------------------------------------------------------
def _read_kinds(data: dict[str, Any], key: str, label: str, kinds: Registry, tables: SceneTables) -> list:
    """Each entry of the array ``key`` read by the registered kind it names (one object, or a list of them)."""
    built = []
    for index, entry in enumerate(list_of_tables(data.get(key, []), key)):
        kind = entry.get("kind")
        if kind not in kinds:
            raise SceneError(f"{key}[{index}]: kind {kind!r} is not a {kinds.kind}; valid kinds: {choices(kinds)}")
        name = tables.name(entry, f"{label}{index}", f"{key}[{index}]")
        made = kinds.entry(kind).factory(entry, tables, name, f"{label} {name!r}")
        built += made if isinstance(made, list) else [made]  # a kind may read one entry into several blocks
    return built


# -- small validators ---------------------------------------------------------------------------
def _check_unique(names: list[str]) -> None:
    twice = repeated(names)
    if twice:
        raise SceneError(f"constraint and force names must be unique; repeated: {', '.join(twice)}")


__all__ = ["Scene", "load_scene", "scene_from_dict"]
