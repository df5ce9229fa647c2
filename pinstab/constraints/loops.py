"""Loop closures between two frames, or a frame and a fixed world placement.

Kinds: ``point`` (3 rows, world axes), ``planar-point`` (2 rows: the point difference projected on
the two axes of a stated plane), ``weld`` (6 rows: point difference in world axes, then the
relative rotation ``log3(R_b^T R_a)``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..errors import ConstraintError, SceneError, choices
from ..kernels import RowBlock
from ..tables import SceneTables, closure_frames, unit
from .base import CONSTRAINT_KINDS, BlockRows

CLOSURE_KINDS = ("point", "planar-point", "weld")
CLOSURE_KEYS = {"name", "kind", "frame_a", "offset_a", "rpy_a", "frame_b", "offset_b", "rpy_b"}
PLANES = {"xy": (0, 1), "xz": (0, 2), "yz": (1, 2)}


def plane_basis(plane: str | np.ndarray) -> np.ndarray:
    """2 x 3 orthonormal basis of a plane given by name (``xy``, ``xz``, ``yz``) or normal."""
    if isinstance(plane, str):
        if plane not in PLANES:
            raise ConstraintError(f"unknown plane {plane!r}; valid planes: {choices(PLANES)} or a normal vector")
        return np.eye(3)[list(PLANES[plane])]
    normal = np.asarray(plane, dtype=float).reshape(-1)
    if normal.shape != (3,) or not np.all(np.isfinite(normal)) or not np.any(normal):
        raise ConstraintError(f"plane normal must be a non-zero 3-vector, got {plane!r}")
    normal = unit(normal)
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    first = np.cross(normal, helper)
    first /= np.linalg.norm(first)
    return np.vstack([first, np.cross(normal, first)])


class FrameClosure(BlockRows):
    """A loop closure between frame ``a`` and frame ``b`` (or the world when ``frame_b`` is None).

    The frames are operational frames that the scene adds at the closure points, so the residual is
    ``p_a - p_b`` with both points in world coordinates [m]. The multipliers are the force [N]
    (and for ``weld`` the moment [N m]) that the closure exerts on body ``a``, in world axes
    (moment rows: in the axes of the relative rotation's log, i.e. frame a at closure); body ``b``
    receives the opposite.
    """

    holonomic = True

    def __init__(
        self,
        name: str,
        kind: str,
        frame_a: int,
        frame_b: int | None,
        world_placement_b: pin.SE3 | None = None,
        plane: str | np.ndarray = "xy",
    ) -> None:
        if kind not in CLOSURE_KINDS:
            raise ConstraintError(f"closure {name}: unknown kind {kind!r}; valid kinds: {choices(CLOSURE_KINDS)}")
        self.name = name
        self.kind = kind
        self.frame_a = frame_a
        self.frame_b = frame_b
        self.world_placement_b = world_placement_b if world_placement_b is not None else pin.SE3.Identity()
        self.selection = plane_basis(plane) if kind == "planar-point" else np.eye(3)
        self.locks_rotation = kind == "weld"  # rotation rows after the point rows
        self.rows = 6 if kind == "weld" else self.selection.shape[0]
        self.force_frame = (
            "world axes (force on a) + log3(R_b^T R_a) axes (moment on a)"
            if kind == "weld"
            else ("world axes, force on a" if kind == "point" else "plane axes, force on a")
        )
        self._block: RowBlock | None = None

    def sides(self, model: pin.Model) -> tuple[tuple[int, pin.SE3], tuple[int, pin.SE3]]:
        """Where the closure's two points sit in ``model``: (joint, placement in the joint's frame) of side a and
        of side b, side b on the world as joint 0 at :attr:`world_placement_b`."""
        frame_a = model.frames[self.frame_a]
        if self.frame_b is None:
            return (frame_a.parentJoint, frame_a.placement), (0, self.world_placement_b)
        frame_b = model.frames[self.frame_b]
        return (frame_a.parentJoint, frame_a.placement), (frame_b.parentJoint, frame_b.placement)

    def compiled_rows(self) -> RowBlock:
        """The closure's rows in the compiled core (``cpp/core_rows.cpp``), which computes them for Python too: built
        at first use (a subclass sets its kind, selection and world placement in its own constructor)."""
        if self._block is None:
            kind, selection = self._block_form()
            frame_b = -1 if self.frame_b is None else self.frame_b
            placement_b = self.world_placement_b.homogeneous
            self._block = RowBlock(kind, self.frame_a, frame_b, placement_b, selection)
        return self._block

    def _block_form(self) -> tuple[int, np.ndarray]:
        """The compiled row kind (``cpp/core_rows.hpp``: 0 point, 1 weld) and its selection (rows x 3)."""
        return (1, np.eye(3)) if self.locks_rotation else (0, self.selection)

    # -- Constraint ------------------------------------------------------------------------------


def _plane(entry: dict, kind: str, where: str) -> str | tuple[float, float, float]:
    if kind != "planar-point":
        return "xy"
    raw = entry.get("plane")
    if isinstance(raw, str) and raw in PLANES:
        return raw
    if isinstance(raw, list):
        return tuple(SceneTables.direction(raw, f"{where}.plane"))  # type: ignore[return-value]
    raise SceneError(f"{where}: 'plane' must be one of {choices(PLANES)} or a normal vector, got {raw!r}")


def parse_closure(kind: str):
    """The scene-table reader of closure kind ``kind``: frames a and b (``world`` by default) with
    offsets [m] and rpy angles [rad]; ``plane`` for ``planar-point``."""

    def parse(entry: dict, tables: SceneTables, name: str, where: str) -> FrameClosure:
        tables.check_keys(entry, CLOSURE_KEYS | ({"plane"} if kind == "planar-point" else set()), where)
        plane = _plane(entry, kind, where)
        return FrameClosure(name, kind, *closure_frames(entry, tables, name, where), plane)

    return parse


CONSTRAINT_KINDS.register("point", parse_closure("point"), summary="3 rows: two frame points coincide (world axes)")
CONSTRAINT_KINDS.register(
    "planar-point", parse_closure("planar-point"), summary="2 rows: two frame points coincide within a plane"
)
CONSTRAINT_KINDS.register("weld", parse_closure("weld"), summary="6 rows: two frames coincide (position and rotation)")
