"""Welded (rigid) grasps for ``grasp-control``: an object held by two hands through two ``weld``
closures, 6 rows each (wrench basis ``rigid``: a weld transmits any wrench) [MLS ch. 5] (docs/mathematics.md section 4).

With the closures' rows ``A = [A_hand, A_object]`` (12 rows), the grasp map is ``G = A_object^T`` (6 x 12:
the closures' multipliers to the wrench on the object, in its body frame O) and the hand Jacobian
``J_h = -A_hand``. The internal forces are the null space of G (6 columns: the forces and moments the two
hands exert against each other). The **squeeze** s [N] is the one along the line between the two grasp
points p_1, p_2 (the closures' frames on the object, world): the hands push the object with s u at p_1 and
-s u at p_2, ``u = (p_2 - p_1) / |p_2 - p_1|`` (s > 0 presses, s < 0 pulls); that is the internal force
``s n`` with ``n = [sigma_1 u, 0, -sigma_2 u, 0]`` in the closures' multipliers, sigma_i = +1 when the
object is the closure's frame a (its multipliers are then the force on the object), -1 when it is frame b.

The controller's forces: the smallest (least-squares) multipliers that give the object the wrench its
motion needs (``G^+ w``, orthogonal to the null space), plus ``s* n`` with the set value s*: the internal
force is exactly the squeeze, its other five components zero. A run measures the internal force as the
projection of the closures' multipliers on the null space of G, its squeeze ``n . lambda / |n|^2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..constraints.loops import FrameClosure
from ..errors import SceneError, choices
from ..kinematics import Kinematics
from ..tables import SceneTables
from .linalg import closest_solution

WELDS = 2  # a squeeze is the internal force between two grasps


@dataclass(frozen=True)
class WeldedGrasp:
    """Two weld closures holding one object, and the squeeze set between them.

    Attributes:
        closures: the two weld closures. object_frames: their frames on the object. signs: sigma_i (+1: the
            closure's multipliers are the force on the object, -1: on the hand). squeeze: the set value s* [N].
    """

    closures: list[FrameClosure]
    object_frames: tuple[int, int]
    signs: tuple[float, float]
    squeeze: float

    def squeeze_direction(self, kin: Kinematics) -> np.ndarray:
        """n (12,): the closures' multipliers of a unit squeeze [N per N] at ``kin``'s placements."""
        first, second = (kin.placement(frame).translation for frame in self.object_frames)
        line = second - first
        direction = np.zeros(6 * WELDS)
        direction[:3] = self.signs[0] * line / np.linalg.norm(line)
        direction[6:9] = -self.signs[1] * line / np.linalg.norm(line)
        return direction

    def forces(self, kin: Kinematics, grasp_map: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """The closures' multipliers (12,) [N, N m] that exert ``wrench`` on the object (body frame, [N, N m])
        through ``grasp_map`` G (6 x 12) with the internal force the squeeze s* alone."""
        return closest_solution(grasp_map, wrench, self.squeeze * self.squeeze_direction(kin))  # n: null space of G

    def internal_force(self, kin: Kinematics, grasp_map: np.ndarray, forces: np.ndarray) -> tuple[float, float]:
        """(the squeeze s [N], the size of the other internal components [N, N m]) of the multipliers
        ``forces``: their projection on the null space of ``grasp_map``, split along n."""
        internal = closest_solution(grasp_map, np.zeros(grasp_map.shape[0]), forces)
        direction = self.squeeze_direction(kin)
        squeeze = float(direction @ internal / (direction @ direction))
        return squeeze, float(np.linalg.norm(internal - squeeze * direction))


def welded_grasp(entry: dict, tables: SceneTables, object_joint: int, where: str) -> WeldedGrasp:
    """The ``closures`` (two weld closures between the object and a hand) and ``squeeze`` [N] of a
    ``grasp-control`` table on the object whose free-flyer joint is ``object_joint``.

    Raises:
        SceneError: not two names, a name that is not a weld on the object, both on one frame, a bad squeeze.
    """
    model = tables.model
    welds = {
        c.name: c
        for c in tables.constraints.values()
        if isinstance(c, FrameClosure) and c.kind == "weld" and _object_side(model, c, object_joint) is not None
    }
    names = entry["closures"]
    if not isinstance(names, list) or len(names) != WELDS or len(set(map(str, names))) != WELDS:
        raise SceneError(
            f"{where}.closures must name two weld closures between the object and a hand, got {names!r}; "
            f"welds on the object: {choices(welds)}"
        )
    for name in names:
        if not isinstance(name, str) or name not in welds:
            raise SceneError(
                f"{where}.closures: {name!r} is not a weld closure between the object and a hand; welds on the "
                f"object: {choices(welds)}"
            )
    closures = [welds[name] for name in names]
    sides = [_object_side(model, c, object_joint) for c in closures]
    frames = tuple(c.frame_a if side > 0 else c.frame_b for c, side in zip(closures, sides, strict=True))
    places = [tables.initial_placement(frame).translation for frame in frames]
    if np.linalg.norm(places[1] - places[0]) < 1e-6:
        raise SceneError(f"{where}.closures: {names[0]!r} and {names[1]!r} hold the object at one point: no squeeze")
    squeeze = tables.quantity(entry.get("squeeze", 0.0), "force", f"{where}.squeeze")
    return WeldedGrasp(closures, frames, tuple(sides), squeeze)


def _object_side(model: pin.Model, closure: FrameClosure, object_joint: int) -> float | None:
    """+1 when the closure's frame a is on the object and frame b on another body (a hand), -1 the other
    way round, None otherwise (the world, both frames on the object, neither)."""
    if closure.frame_b is None:
        return None
    on_object = [model.frames[frame].parentJoint == object_joint for frame in (closure.frame_a, closure.frame_b)]
    if on_object == [True, False]:
        return 1.0
    if on_object == [False, True]:
        return -1.0
    return None
