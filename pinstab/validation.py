"""Physical validity checked when a scene loads: the scene file (size, encoding, nesting), the robot's
frames, locked joints, closures and the initial configuration (a URDF's links are checked by
:mod:`pinstab.readers.urdf_checks`).

Every failure is a :class:`~pinstab.errors.SceneError` naming the item. The checks are one pass over
the file, the URDF's links and the model's joints and frames (no Pinocchio data is allocated: that
grows with nv^2 and more): they cost little next to a simulation. A mass matrix found singular later
(at assembly) is named by :func:`singular_mass_error`.

Quaternions (free-flyer and spherical joints) and unit complex numbers (planar joints) in ``initial.q``
are normalized when their norm is within :data:`UNIT_TOLERANCE` of 1 (rounded values such as 0.7071),
and refused otherwise (a zero norm, or a norm that is rather a mistake than a rounding).
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from .constraints import Constraint, FrameClosure
from .errors import SceneError, repeated
from .tables import WORLD
from .units import COORDINATE_REASON, MAX_COORDINATE, MAX_RATE, RATE_REASON, within_ceiling

MAX_SCENE_BYTES = 1_000_000
MAX_DEPTH = 20
UNIT_TOLERANCE = 1e-3
# (first, end) of the unit part of a joint's configuration: quaternion [qx, qy, qz, qw] or [cos, sin]
UNIT_PARTS = {"JointModelFreeFlyer": (3, 7), "JointModelSpherical": (0, 4), "JointModelPlanar": (2, 4)}


# -- scene files ---------------------------------------------------------------------------------
def read_scene_file(path: Path) -> dict[str, Any]:
    """The parsed content of a scene file: at most :data:`MAX_SCENE_BYTES` bytes of UTF-8 TOML."""
    try:
        size = path.stat().st_size
        if size > MAX_SCENE_BYTES:
            raise SceneError(f"scene file {path}: {size} bytes, more than the limit of {MAX_SCENE_BYTES} bytes")
        raw = path.read_bytes()
    except OSError as exc:
        raise SceneError(f"scene file {path}: cannot be read: {exc.strerror}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"scene file {path}: not UTF-8 text (byte {exc.start}: {raw[exc.start]:#04x})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"scene file {path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise SceneError(f"scene file {path}: tables or arrays nested more than {MAX_DEPTH} levels deep") from None


def check_depth(data: Any, where: str) -> None:
    """Refuse tables or arrays nested more than :data:`MAX_DEPTH` levels deep (without recursion)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise SceneError(f"{where}: tables or arrays nested more than {MAX_DEPTH} levels deep")
        children = value.values() if isinstance(value, dict) else value if isinstance(value, list) else ()
        stack += [(child, depth + 1) for child in children if isinstance(child, (dict, list))]


def check_locked_joints(locked: list[str]) -> None:
    """Refuse a joint listed twice in ``robot.locked_joints``."""
    twice = repeated(locked)
    if twice:
        raise SceneError(f"robot.locked_joints: joint {twice[0]!r} is listed more than once")


def check_model(model: pin.Model) -> None:
    """A model that can move: nv > 0, no frame shadowing ``world``, every moving joint carrying some mass
    or inertia (on its link or a descendant's: otherwise the mass matrix has a zero row and is singular)."""
    if model.nv == 0:
        raise SceneError(
            "scene: the model has no degree of freedom (nv = 0): every joint is locked or fixed; "
            "leave a joint out of robot.locked_joints"
        )
    _check_world_frames(model)
    _check_magnitudes(model)
    _check_moving_mass(model)


def _check_world_frames(model: pin.Model) -> None:
    for frame in model.frames:
        if frame.name == WORLD and (frame.parentJoint != 0 or not frame.placement.isIdentity()):
            raise SceneError(
                f"robot: frame {WORLD!r} (on joint {model.names[frame.parentJoint]!r}) shadows pinstab's world "
                "frame; rename the link"
            )


def _check_magnitudes(model: pin.Model) -> None:
    """Every body's mass [kg] and principal moments of inertia [kg m^2] at most
    :data:`~pinstab.units.MAX_MAGNITUDE` (whichever reader built the model)."""
    for joint_id, inertia in enumerate(model.inertias):
        where = f"robot: the body of joint {model.names[joint_id]!r}"
        within_ceiling(inertia.mass, f"{where}: mass", "kg")
        within_ceiling(float(np.abs(inertia.inertia).max()), f"{where}: inertia", "kg m^2")


def _check_moving_mass(model: pin.Model) -> None:
    """One pass from the leaves up (a parent's index is smaller than its children's)."""
    carries = [inertia.mass > 0 or bool(np.any(inertia.inertia)) for inertia in model.inertias]
    for joint_id in range(model.njoints - 1, 0, -1):
        carries[model.parents[joint_id]] |= carries[joint_id]
    for joint_id in range(1, model.njoints):
        if not carries[joint_id]:
            links = [f.name for f in model.frames if f.parentJoint == joint_id and f.type == pin.FrameType.BODY]
            raise SceneError(
                f"robot: joint {model.names[joint_id]!r} (link {', '.join(links) or '(none)'}) moves no mass or "
                "inertia (zero mass and zero inertia on it and its descendants): the mass matrix is singular"
            )


def singular_mass_error(model: pin.Model, mass: np.ndarray, where: str) -> SceneError:
    """The error for a mass matrix found singular at ``where``: it names the joints whose combined motion
    moves no mass or inertia (the largest entries of the eigenvector of the smallest eigenvalue)."""
    eigenvalues, vectors = np.linalg.eigh(mass)
    null = np.abs(vectors[:, 0])
    joints = [
        model.names[j]
        for j in range(1, model.njoints)
        if np.any(null[model.joints[j].idx_v : model.joints[j].idx_v + model.joints[j].nv] > 0.1 * null.max())
    ]
    return SceneError(
        f"robot: the mass matrix is singular at {where} (smallest eigenvalue {eigenvalues[0]:.3g}): moving "
        f"joints {', '.join(repr(j) for j in joints)} together moves no mass or inertia (a massless link between "
        "joints that turn or slide alike, e.g. a massless free-flyer root); give that link mass and inertia, or "
        "lock one of the joints"
    )


def check_closures(model: pin.Model, constraints: list[Constraint]) -> None:
    """Refuse a closure between two frames of one rigid body (a frame and itself): its rows are zero."""
    for constraint in constraints:
        if not isinstance(constraint, FrameClosure):
            continue
        (joint_a, _), (joint_b, _) = constraint.sides(model)
        if joint_a == joint_b:
            raise SceneError(
                f"constraint {constraint.name!r}: both frames are on the same rigid body (joint "
                f"{model.names[joint_a]!r}): a closure between a frame and itself; its rows are zero"
            )


# -- configurations ------------------------------------------------------------------------------
def check_configuration(model: pin.Model, q: np.ndarray, where: str) -> None:
    """Refuse an entry of ``q`` beyond :data:`MAX_COORDINATE` [m or rad]; normalize (in place) each quaternion
    and unit complex number of ``q`` whose norm is within :data:`UNIT_TOLERANCE` of 1; refuse any other."""
    for index in np.flatnonzero(~(np.abs(q) <= MAX_COORDINATE)):
        joint_id = next(j for j in range(1, model.njoints) if index < model.idx_qs[j] + model.nqs[j])
        raise SceneError(
            f"{where}.{model.names[joint_id]}: {q[index]:g} is beyond {MAX_COORDINATE:g} m or rad, {COORDINATE_REASON}"
        )
    for joint_id in range(1, model.njoints):
        joint = model.joints[joint_id]
        part = UNIT_PARTS.get(joint.shortname())
        if part is None:
            continue
        unit = q[joint.idx_q + part[0] : joint.idx_q + part[1]]
        norm = float(np.linalg.norm(unit))
        if abs(norm - 1.0) > UNIT_TOLERANCE:
            raise SceneError(
                f"{where}.{model.names[joint_id]}: {unit.tolist()} is not a unit quaternion or complex number "
                f"(norm {norm:.6g}; only a norm within {UNIT_TOLERANCE} of 1 is normalized)"
            )
        unit /= norm


def check_velocity(model: pin.Model, v: np.ndarray, where: str) -> None:
    """Refuse an entry of ``v`` (joint rates, a free joint's twist) beyond :data:`~pinstab.units.MAX_RATE`
    [rad/s or m/s] in size, naming the joint (and the entry of a joint of several)."""
    for index in np.flatnonzero(~(np.abs(v) <= MAX_RATE)):
        joint_id = next(j for j in range(1, model.njoints) if index < model.idx_vs[j] + model.nvs[j])
        entry = "" if model.nvs[joint_id] == 1 else f"[{index - model.idx_vs[joint_id]}]"
        raise SceneError(
            f"{where}.{model.names[joint_id]}{entry}: {v[index]:g} is outside [-{MAX_RATE:g}, {MAX_RATE:g}] rad/s or "
            f"m/s, {RATE_REASON}"
        )


# -- tolerances ----------------------------------------------------------------------------------
def relative_tolerance(value: Any, where: str, meaning: str = "a fraction of the mechanism's size") -> float:
    """A relative tolerance [-]: a number in (0, 1); SceneError naming ``where`` (and what it is relative to,
    ``meaning``) otherwise (negative, zero, NaN, infinite, at least 1, not a number)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 < value < 1.0:
        raise SceneError(
            f"{where} must be a relative tolerance, a number in (0, 1) such as 1e-10 ({meaning}), got {value!r}"
        )
    return float(value)
