"""Reading scene-file tables: keys, numbers with units, vectors, placements, and the model's frames
and joints by name. Every failure is a :class:`~pinstab.errors.SceneError` naming the item and the
valid alternatives. Constraint and force kinds read their own tables through :class:`SceneTables`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from .errors import SceneError, choices
from .memory import new_data
from .units import COORDINATE_REASON, MAX_COORDINATE, finite_number, quantity

WORLD = "world"
FRAME_PREFERENCE = (pin.FrameType.BODY, pin.FrameType.OP_FRAME, pin.FrameType.FIXED_JOINT, pin.FrameType.JOINT)
MIN_SCENE_SIZE = 1.0  # [m] the size of a smaller scene (a hand, a pendulum): its lengths keep their digits anyway
MAX_REACH = 10.0  # [-] scene sizes: the farthest a point read on a body (a contact, closure or target point, a
# fingertip's radius) may lie from its frame's origin, or a point on the world from the world's origin. The scene's
# size bounds every body's frames and mass; a point ten times farther is on no body of the scene (a typing or
# unit mistake: 1e6 for 1e-6), and next to the scene's lengths it leaves float64 fewer digits for them


def toml_scalar(text: str) -> Any:
    """``text`` read as a TOML value (``20`` an int, ``0.5`` a float, ``true`` a bool, ``"a"`` a string), else
    the text itself (``baumgarte``)."""
    import tomllib

    try:
        return tomllib.loads(f"x = {text}")["x"]
    except tomllib.TOMLDecodeError:
        return text


def check_keys(table: dict[str, Any], allowed: set[str], where: str) -> None:
    """Refuse a key outside ``allowed``."""
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise SceneError(f"{where}: unknown key {unknown[0]!r}; valid keys: {choices(allowed)}")


def table(value: Any, where: str) -> dict[str, Any]:
    """A required TOML table."""
    if value is None:
        raise SceneError(f"scene: the [{where}] table is required")
    if not isinstance(value, dict):
        raise SceneError(f"{where} must be a table, got {type(value).__name__}")
    return value


def list_of_tables(value: Any, where: str) -> list[dict[str, Any]]:
    """A TOML array of tables (``[[where]]``)."""
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise SceneError(f"{where} must be an array of tables ([[{where}]])")
    return value


def vector(value: Any, size: int, where: str, dimension: str | None) -> np.ndarray:
    """A list of ``size`` numbers (SI, or with units of ``dimension``)."""
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


def unit(vector: np.ndarray) -> np.ndarray:
    """A finite, non-zero ``vector`` scaled to length 1, first to its largest entry (the norm of 1e300 or 1e-300
    overflows or underflows)."""
    scaled = np.asarray(vector, dtype=float) / np.abs(vector).max()
    return scaled / np.linalg.norm(scaled)


def length(vector: np.ndarray | float) -> float:
    """The Euclidean length of ``vector`` at any scale, scaled first to its largest entry (the length of [1, 1e200,
    1] is 1e200, not infinity); infinite beyond float64's range, NaN with a NaN entry."""
    values = np.asarray(vector, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        scale = float(np.abs(values).max(initial=0.0))
        return scale * float(np.linalg.norm(values / scale)) if scale else 0.0


def direction(value: Any, where: str) -> np.ndarray:
    """A direction: a list of 3 numbers, not all zero (any scale), as a unit vector."""
    raw = vector(value, 3, where, None)
    if not np.any(raw):
        raise SceneError(f"{where} must be a non-zero vector (a direction), got {value!r}")
    return unit(raw)


def coordinates(values: np.ndarray, where: str, unit: str) -> np.ndarray:
    """``values`` [m or rad] when each is within :data:`~pinstab.units.MAX_COORDINATE`, as a joint coordinate."""
    if not np.all(np.abs(values) <= MAX_COORDINATE):
        raise SceneError(f"{where} = {values.tolist()} {unit} is beyond {MAX_COORDINATE:g} {unit}, {COORDINATE_REASON}")
    return values


def placement(entry: dict[str, Any], offset_key: str, rpy_key: str, where: str) -> pin.SE3:
    """An SE3 from an offset [m] and roll-pitch-yaw angles [rad] (both optional, zero by default; the angles within
    :data:`~pinstab.units.MAX_COORDINATE`)."""
    offset = vector(entry.get(offset_key, [0.0, 0.0, 0.0]), 3, f"{where}.{offset_key}", "length")
    rpy = vector(entry.get(rpy_key, [0.0, 0.0, 0.0]), 3, f"{where}.{rpy_key}", "angle")
    return pin.SE3(pin.rpy.rpyToMatrix(coordinates(rpy, f"{where}.{rpy_key}", "rad")), offset)


def joint_id(model: pin.Model, name: Any, where: str) -> int:
    """A joint's index; SceneError listing the joints otherwise."""
    if not isinstance(name, str) or not model.existJointName(name) or name == "universe":
        valid = [n for n in model.names if n != "universe"]
        raise SceneError(f"{where}: unknown joint {name!r}; valid joints: {choices(valid)}")
    return model.getJointId(name)


def frame_id(model: pin.Model, name: Any, where: str) -> int:
    """A frame's index; a link (BODY) frame wins over a joint frame of the same name."""
    if isinstance(name, str):
        for frame_type in FRAME_PREFERENCE:
            if model.existFrame(name, frame_type):
                return model.getFrameId(name, frame_type)
    valid = [f.name for f in model.frames if f.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME)]
    raise SceneError(f"{where}: unknown frame {name!r}; valid frames: {WORLD}, {choices(valid)}")


def joint_placements(model: pin.Model, q: np.ndarray) -> list[pin.SE3]:
    """The world placement of every joint of ``model`` at configuration ``q``, in one pass from the root (a parent's
    index is smaller than its children's), without a Pinocchio ``Data`` (one grows as nv^3)."""
    placements = [pin.SE3.Identity()]
    for joint in range(1, model.njoints):
        motion = model.joints[joint].createData()
        model.joints[joint].calc(motion, q)
        placements.append(placements[model.parents[joint]] * model.jointPlacements[joint] * motion.M)
    return placements


def body_groups(model: pin.Model) -> list[int]:
    """Each joint's group: the index of the free-flyer joint at the root of its tree (an object, a floating robot),
    else 0 (the world and the trees mounted on it: a fixed robot)."""
    groups = [0]
    for joint in range(1, model.njoints):
        parent = model.parents[joint]
        floating = parent == 0 and model.joints[joint].shortname() == "JointModelFreeFlyer"
        groups.append(joint if floating else groups[parent])
    return groups


def group_points(model: pin.Model, q: np.ndarray) -> list[np.ndarray]:
    """For each group of :func:`body_groups`, the world points [m] (k, 3) at configuration ``q`` of its joints' and
    frames' origins and its bodies' centres of mass (the world's group holds the world's origin)."""
    joints = joint_placements(model, q)
    groups = body_groups(model)
    points: dict[int, list[np.ndarray]] = {}
    for joint, inertia in enumerate(model.inertias):
        points.setdefault(groups[joint], []).extend((joints[joint].translation, joints[joint].act(inertia.lever)))
    for frame in model.frames:
        points[groups[frame.parentJoint]].append((joints[frame.parentJoint] * frame.placement).translation)
    return [np.array(group) for group in points.values()]


@np.errstate(over="ignore", invalid="ignore")  # a model too large for floating point: an infinite size
def scene_size(model: pin.Model, q: np.ndarray) -> float:
    """The scene's size [m]: its largest group of bodies' extent at configuration ``q`` (:func:`body_groups`: the
    diagonal of the box holding the origins of the group's joints and frames and its bodies' centres of mass), or
    the largest body's gyration diameter ``2 sqrt(tr(I_c) / m)`` (a box of side s: 1.41 s) if larger, at least
    :data:`MIN_SCENE_SIZE`. The distances between groups do not count: a ball a million metres from the world's
    origin (or from the robot) is as large as at the origin, and moving a scene leaves its size as it was."""
    extents = [float(np.linalg.norm(np.ptp(group, axis=0))) for group in group_points(model, q)]
    gyration = [2.0 * np.sqrt(np.trace(i.inertia) / i.mass) for i in model.inertias if i.mass > 0]
    return max(MIN_SCENE_SIZE, *extents, *gyration)


class SceneTables:
    """What a constraint or force kind needs to read its scene table: the (reduced) model, to which
    it may add operational frames at its points.

    Args:
        model: the scene's Pinocchio model (frames are added to it).
        q0: the scene's declared initial configuration (a kind may move joints in it, in place: a
            fingertip contact closes its gap).
        objects: the scene's rigid objects by name (:class:`~pinstab.contact.objects.SceneObject`).

    Attributes:
        claimed_joints: joints a kind has positioned in ``q0``, with the item that did (a later item
            leaves them alone).
        constraints: the scene's constraint blocks by name, once they are read (force kinds see them).
        size: the scene's size [m] at ``q0`` (:func:`scene_size`), before any kind adds a frame; the points the
            kinds read are checked against it (:meth:`within_reach`).
        bounds: the lowest and highest corners [m] of the box holding the scene's joints, frames and centres of
            mass at ``q0`` (:func:`group_points`), from which points on the world are measured.
        robot_shapes: the robot's collision geometry (indices of ``model``), built when called (the scene sets it;
            raises :class:`~pinstab.errors.SceneError` when it cannot be built); empty by default.
        contact_finders: the finders of contacts from geometry the kinds made
            (:class:`~pinstab.constraints.geometry_contacts.FoundContacts`).
    """

    def __init__(self, model: pin.Model, q0: np.ndarray, objects: dict[str, Any] | None = None) -> None:
        self.model = model
        self.q0 = q0
        self.objects = objects or {}
        self.claimed_joints: dict[int, str] = {}
        self.constraints: dict[str, Any] = {}
        self.size = scene_size(model, q0)
        every = np.vstack(group_points(model, q0))
        self.bounds = (every.min(axis=0), every.max(axis=0))  # [m] the box holding every group's points
        self.robot_shapes: Callable[[], pin.GeometryModel] = pin.GeometryModel
        self.contact_finders: list[Any] = []

    check_keys = staticmethod(check_keys)
    vector = staticmethod(vector)
    direction = staticmethod(direction)
    placement = staticmethod(placement)
    quantity = staticmethod(quantity)

    def joint_id(self, name: Any, where: str) -> int:
        """A joint's index by name."""
        return joint_id(self.model, name, where)

    def frame_id(self, name: Any, where: str) -> int:
        """A frame's index by name."""
        return frame_id(self.model, name, where)

    def within_reach(self, point: np.ndarray | float, where: str, on_world: bool = False) -> None:
        """Refuse a point [m] (a 3-vector on a body, in its frame's axes) or a length on a body farther than
        :data:`MAX_REACH` times :attr:`size` from its frame's origin; ``on_world``: a point on the world, measured
        from the box of the scene's bodies (:attr:`bounds`), wherever the scene lies."""
        offset = np.asarray(point, dtype=float)
        if on_world:
            with np.errstate(invalid="ignore"):  # an infinite point: a NaN distance, refused
                offset = offset - np.clip(offset, *self.bounds)
        distance = length(offset)  # beyond floating point: infinite, refused
        limit = MAX_REACH * self.size
        if not distance <= limit:
            shown = f"[{', '.join(f'{x:.6g}' for x in point)}]" if np.ndim(point) else f"{point:.6g}"
            origin = "the scene's bodies" if on_world else "its frame's origin"
            raise SceneError(
                f"{where} = {shown} m lies {distance:.3g} m from {origin}, beyond {MAX_REACH:g} times the scene's "
                f"size ({self.size:.3g} m: its largest group of bodies at the start), the allowed range [0, "
                f"{limit:.3g}] m: a point that far is on no body of the scene (check its value and unit)"
            )

    def point_frame(self, frame_name: Any, offset: pin.SE3, new_name: str, where: str) -> int:
        """Add an operational frame ``new_name`` at ``offset`` in frame ``frame_name``; its index."""
        parent = self.frame_id(frame_name, where)
        frame = self.model.frames[parent]
        return self.model.addFrame(
            pin.Frame(new_name, frame.parentJoint, parent, frame.placement * offset, pin.FrameType.OP_FRAME)
        )

    def attached_frame(
        self, entry: dict[str, Any], frame_key: str, offset_key: str, rpy_key: str, new_name: str, where: str
    ) -> int:
        """The operational frame ``new_name`` at ``entry[offset_key]`` [m] and ``entry[rpy_key]`` [rad] in
        the required frame ``entry[frame_key]``; its index."""
        if frame_key not in entry:
            raise SceneError(f"{where}: {frame_key!r} is required")
        offset = placement(entry, offset_key, rpy_key, where)
        self.within_reach(offset.translation, f"{where}.{offset_key}")
        return self.point_frame(entry[frame_key], offset, new_name, f"{where}.{frame_key}")

    def initial_placement(self, frame: int) -> pin.SE3:
        """World placement of a frame at the declared initial configuration."""
        data = new_data(self.model)
        pin.framesForwardKinematics(self.model, data, self.q0)
        return data.oMf[frame].copy()  # not a view into data, which goes out of scope

    def number(self, entry: dict[str, Any], key: str, where: str, default: float | None = None) -> float:
        """A plain number (dimensionless) from ``entry[key]``."""
        value = entry.get(key, default)
        if value is None:
            raise SceneError(f"{where}: {key!r} is required")
        return finite_number(value, f"{where}.{key}")

    def name(self, entry: dict[str, Any], default: str, where: str) -> str:
        """The entry's ``name`` (a string) or ``default``."""
        value = entry.get("name", default)
        if not isinstance(value, str) or not value:
            raise SceneError(f"{where}.name must be a non-empty string, got {value!r}")
        return value


def closure_frames(entry: dict, tables: SceneTables, name: str, where: str) -> tuple[int, int | None, pin.SE3 | None]:
    """A closure entry's two sides: the operational frame of side a (``frame_a`` at ``offset_a``/``rpy_a``), and
    side b's frame (None for the world) or, on the world, its placement (``offset_b`` [m], ``rpy_b`` [rad])."""
    frame_a = tables.attached_frame(entry, "frame_a", "offset_a", "rpy_a", f"{name}/a", where)
    offset_b = tables.placement(entry, "offset_b", "rpy_b", where)
    on_world = entry.get("frame_b", WORLD) == WORLD
    tables.within_reach(offset_b.translation, f"{where}.offset_b", on_world)
    if on_world:
        return frame_a, None, offset_b
    return frame_a, tables.point_frame(entry["frame_b"], offset_b, f"{name}/b", f"{where}.frame_b"), None
