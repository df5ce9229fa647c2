"""A scene's grasps analysed at its assembled start: per object, its fingertip contacts, the grasp map,
the hand Jacobian, their ranks, manipulability, force closure, internal forces and quality
(``pinstab grasp SCENE``).

Frames and units: O is the object's body frame, C_i contact i's frame (z the normal into the object).
G takes the contact forces [N, N m] in their C_i to the object wrench in O [N, N m]; J_h takes the hand's
joint rates [rad/s or m/s] to the fingertip velocities in the C_i [m/s, rad/s], so that the contacts hold
when ``J_h theta_dot = G^T x_dot`` (x_dot the object's body twist, linear first) [MLS ch. 5].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..assembly import assemble
from ..errors import PinstabError, choices
from ..model import ConstrainedModel
from ..scene import Scene
from .analysis import RANK_TOLERANCE, GraspAnalysis, GraspContact, analyse_grasp
from .capacity import Capacity, Weight, grasp_capacity, horizontal_axes
from .hold import contact_rows
from .holding import HOLD_MARGIN, narrowed

FRAMES = {
    "grasp_map": "contact forces in C_i [N, N m] -> object wrench in O [N, N m]",
    "hand_jacobian": "hand joint rates [rad/s, m/s] -> fingertip velocities in C_i [m/s, rad/s]",
    "internal_forces": "contact forces in C_i [N, N m] (unit columns) that load the object without moving it",
    "quality": "Ferrari-Canny epsilon [N]: moments divided by the length, unit total normal force",
    "object_twist_singular_values": "object twist (O, linear first) [m/s, rad/s] per unit joint rate",
    "load_n": "the object's weight m |g| [N]",
    "squeeze_needed_n": "the least largest contact normal force that holds the weight, exact round cones [N]",
    "largest_load_n": "the largest weight (along the scene's gravity) the squeeze holds [N]",
    "first_slip_tilt_deg": "per world axis and sense: the hand's tilt at which the first contact leaves its cone [deg]",
}


def _rank(matrix: np.ndarray) -> int:
    if matrix.size == 0:
        return 0
    singular = np.linalg.svd(matrix, compute_uv=False)
    return int(np.count_nonzero(singular > RANK_TOLERANCE * max(float(singular[0]), 1.0)))


@dataclass
class ObjectGrasp:
    """One object's grasp at the start.

    Attributes:
        object: its name. contacts: the grasp contact blocks on it, in scene order.
        analysis: G, its rank, internal forces, force closure, quality (:class:`~pinstab.grasp.analysis.GraspAnalysis`).
        contact_geometry: the contacts as the analysis sees them (position and axes in O).
        hand_jacobian: J_h (sum of rows x hand DOF). hand_columns: the hand's velocity indices.
        hand_rank: rank of J_h. manipulable: every object twist can be produced by the hand (range
            G^T within range J_h). twist_singular_values: singular values of (G^T)^+ J_h.
        row_mismatch: the largest difference between G^T and the contact rows' object columns (a
            consistency check of the two constructions; round-off at the start).
        weight: the object's weight as the grasp sees it. capacity: the squeeze it needs, the largest load
            and tilts (:class:`~pinstab.grasp.capacity.Capacity`).
    """

    object: str
    contacts: list[Any]
    analysis: GraspAnalysis
    contact_geometry: list[GraspContact]
    hand_jacobian: np.ndarray
    hand_columns: np.ndarray
    hand_rank: int
    manipulable: bool
    twist_singular_values: np.ndarray
    row_mismatch: float
    weight: Weight
    capacity: Capacity

    def to_json(self) -> dict[str, Any]:
        """The figures ``pinstab grasp --json`` prints for this object."""
        analysis = self.analysis
        return {
            "contacts": {
                geometry.name: {
                    "model": geometry.model,
                    "columns": int(geometry.basis.shape[1]),
                    "position_m": geometry.position.tolist(),
                    "normal": geometry.rotation[:, 2].tolist(),
                    "mu": geometry.mu,
                    "torsion_m": geometry.torsion,
                }
                for geometry in self.contact_geometry
            },
            "grasp_map_shape": list(analysis.grasp_map.shape),
            "grasp_map_rank": analysis.rank,
            "smallest_singular_value": analysis.smallest_singular_value,
            "hand_jacobian_shape": list(self.hand_jacobian.shape),
            "hand_jacobian_rank": self.hand_rank,
            "manipulable": self.manipulable,
            "object_twist_singular_values": self.twist_singular_values.tolist(),
            "force_closure": analysis.force_closure,
            "unresisted_wrench": None if analysis.unresisted is None else analysis.unresisted.tolist(),
            "internal_force_dimension": int(analysis.internal_forces.shape[1]),
            "quality": analysis.quality,
            "quality_length_m": analysis.length,
            **_capacity_json(self.capacity),
            "grasp_map": analysis.grasp_map.tolist(),
            "frames": FRAMES,
        }


def _capacity_json(capacity: Capacity) -> dict[str, Any]:
    def finite(value: float | None) -> float | None:
        return None if value is None or math.isinf(value) else value

    return {
        "load_n": capacity.load,
        "squeeze_needed_n": finite(capacity.squeeze_needed),
        "squeeze_n": capacity.squeeze,
        "largest_load_n": finite(capacity.largest_load),
        "first_slip_tilt_deg": {axis: finite(tilt) for axis, tilt in capacity.tilts.items()},
    }


def hold_squeeze(scene: Scene, name: str) -> float | None:
    """The squeeze [N] of the scene's ``grasp-hold`` on object ``name`` (its cap ``max_squeeze`` when
    finite), or None when no hold presses it."""
    for element in scene.forces:
        if getattr(element, "kind", None) == "grasp-hold" and element.object_name == name:
            cap = element.max_squeeze
            return cap if math.isfinite(cap) else (element.squeeze or None)
    return None


def analyse_scene_grasps(
    scene: Scene,
    facets: int = 8,
    squeeze: float | None = None,
    tilt_axis: np.ndarray | None = None,
    margin: float = 0.0,
) -> dict[str, ObjectGrasp]:
    """Every grasped object's :class:`ObjectGrasp` at the scene's assembled start, cones linearized with
    ``facets`` sides for force closure and quality; the squeeze its weight needs on the exact cones, and
    for ``squeeze`` [N] (default: the scene's ``grasp-hold`` on the object, see :func:`hold_squeeze`) the
    largest load and the first slipping tilt about ``tilt_axis`` (world; default: the two horizontal
    world axes), both senses; the capacity on the cones narrowed by ``margin`` (relative: a ``grasp-hold``'s
    :data:`~pinstab.grasp.holding.HOLD_MARGIN` gives where the hold lets go; default 0: the contacts' own cones).

    Raises:
        PinstabError: the scene has no grasp contacts (naming its objects); AssemblyError from assembly.
    """
    grasped: dict[str, list[Any]] = {}
    for constraint in scene.constraints:
        if constraint.kind == "grasp-contact":
            grasped.setdefault(constraint.object_name, []).append(constraint)
    if not grasped:
        raise PinstabError(
            f"scene {scene.name} has no grasp contacts (kind 'grasp-contact'); objects: "
            f"{choices(o.name for o in scene.objects)}"
        )
    if squeeze is not None and not (math.isfinite(squeeze) and squeeze > 0):
        raise PinstabError(f"squeeze must be a positive number of newtons, got {squeeze!r}")
    gravity = np.array(scene.model.gravity.linear)
    if tilt_axis is None:
        axes = horizontal_axes(gravity) if np.linalg.norm(gravity) > 0 else {}
    else:
        axis = np.asarray(tilt_axis, float)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or not np.any(axis):
            raise PinstabError(f"the tilt axis must be three finite numbers, not all zero, got {tilt_axis!r}")
        axis = axis / np.abs(axis).max()  # first to its largest entry: the norm of 1e300 or 1e-300 is inf or 0
        axes = {"axis": axis / np.linalg.norm(axis)}
    model = ConstrainedModel(scene)
    start = assemble(model, scene.q0, scene.v0)
    model.kin.update_jacobians(start.q)
    return {
        name: _object_grasp(
            model, name, contacts, facets, hold_squeeze(scene, name) if squeeze is None else squeeze, axes, margin
        )
        for name, contacts in grasped.items()
    }


def tilt_at_first_slip(
    scene: Scene, axis: np.ndarray, squeeze: float | None = None, object_name: str | None = None
) -> float:
    """The tilt [deg] of the hand about the world ``axis`` (right-handed; the hand feels gravity turned by
    minus that angle) at which the first contact of the grasp on ``object_name`` (default: the scene's
    only grasped object) leaves its cone, when every contact presses with at most ``squeeze`` [N] (default:
    the scene's ``grasp-hold`` on the object, :func:`hold_squeeze`): the smallest tilt in (0, 180] deg at
    which no contact forces inside the round cones narrowed as a ``grasp-hold`` narrows them
    (:data:`~pinstab.grasp.holding.HOLD_MARGIN`) with normal forces <= squeeze hold the object's weight,
    computed at the scene's assembled start to 1e-6 deg. 0 when the grasp does not hold untilted, inf when
    it holds at every tilt. A ``grasp-hold`` with ``max_squeeze`` equal to that squeeze lets go there (on the
    contacts' own cones, ``pinstab grasp``'s ``first_slip_tilt_deg``, the bound is later: 3.4e-4 deg on
    allegro-tilt).

    Raises:
        PinstabError: no grasp contacts, an unknown object, no squeeze given or found, a bad axis.
    """
    grasps = analyse_scene_grasps(scene, squeeze=squeeze, tilt_axis=axis, margin=HOLD_MARGIN)
    if object_name is None and len(grasps) > 1:
        raise PinstabError(f"scene {scene.name} grasps several objects; name one of {choices(grasps)}")
    name = object_name if object_name is not None else next(iter(grasps))
    if name not in grasps:
        raise PinstabError(f"scene {scene.name} has no grasp on {name!r}; grasped objects: {choices(grasps)}")
    grasp = grasps[name]
    if grasp.capacity.squeeze is None:
        raise PinstabError(f"scene {scene.name} has no grasp-hold on {name!r}: give the squeeze [N]")
    return grasp.capacity.tilts["+axis"]


def slips_under_tilt(scene: Scene, facets: int = 8) -> dict[str, dict[str, float | None]]:
    """Under the scene's ``[tilt]`` (its axis, turned in the sense of its rate from ``start`` until ``stop``), per
    grasped object: ``first_slip_tilt_deg`` and ``first_slip_t_s``, where the first contact leaves its own cone
    (``pinstab grasp``'s ``first_slip_tilt_deg`` about that axis), and with a ``grasp-hold`` on the object
    ``hold_lets_go_tilt_deg`` and ``hold_lets_go_t_s``, where the hold lets go (:func:`tilt_at_first_slip`: its
    cones narrowed by :data:`~pinstab.grasp.holding.HOLD_MARGIN`; an event-driven run's first slip). Tilts [deg]
    about the turn's axis from the untilted hand, times [s] from the run's start (0 where the start is past it);
    None where the turn never reaches it (the grasp holds at every tilt, or the turn stops before). Empty without a
    tilt."""
    tilt = scene.tilt
    if tilt is None:
        return {}
    sense = math.copysign(1.0, tilt.rate)
    axis, reached = sense * tilt.axis, sense * tilt.stop

    def when(angle: float) -> float | None:
        """The time [s] the turn reaches ``angle`` [deg] about ``axis``, None if never."""
        turned = math.radians(angle)
        if not math.isfinite(turned) or turned > reached:
            return None
        return max(0.0, (turned - sense * tilt.start) / abs(tilt.rate))

    slips: dict[str, dict[str, float | None]] = {}
    for margin, key in ((0.0, "first_slip"), (HOLD_MARGIN, "hold_lets_go")):
        for name, grasp in analyse_scene_grasps(scene, facets, tilt_axis=axis, margin=margin).items():
            if grasp.capacity.squeeze is None or (margin and hold_squeeze(scene, name) is None):
                continue
            angle = grasp.capacity.tilts["+axis"]
            slips.setdefault(name, {}).update(
                {f"{key}_tilt_deg": angle if math.isfinite(angle) else None, f"{key}_t_s": when(angle)}
            )
    return slips


def _object_grasp(
    model: ConstrainedModel,
    name: str,
    contacts: list[Any],
    facets: int,
    squeeze: float | None,
    axes: dict,
    margin: float,
) -> ObjectGrasp:
    kin = model.kin
    item = next(o for o in model.scene.objects if o.name == name)
    joint = model.model.joints[item.joint]
    object_columns = np.arange(joint.idx_v, joint.idx_v + joint.nv)
    body = kin.placement(item.frame)
    geometry = []
    for contact in contacts:
        frame = body.actInv(kin.placement(contact.object_frame))
        geometry.append(
            GraspContact(contact.name, contact.model, frame.translation, frame.rotation, contact.mu, contact.torsion)
        )
    rows = contact_rows(contacts, kin, 0.0)
    in_use = np.flatnonzero(np.any(rows != 0.0, axis=0))
    hand_columns = np.setdiff1d(in_use, object_columns)
    hand = -rows[:, hand_columns]
    length = max(float(np.max([np.linalg.norm(g.position) for g in geometry])), 1e-3)
    analysis = analyse_grasp(geometry, facets=facets, length=length)
    transpose = analysis.grasp_map.T
    twist = np.linalg.pinv(transpose) @ hand
    hand_rank = _rank(hand)
    inertia = model.model.inertias[item.joint]
    weight = Weight(inertia.mass, np.array(inertia.lever), np.array(model.model.gravity.linear), body.rotation)
    return ObjectGrasp(
        object=name,
        contacts=contacts,
        analysis=analysis,
        contact_geometry=geometry,
        hand_jacobian=hand,
        hand_columns=hand_columns,
        hand_rank=hand_rank,
        manipulable=_rank(np.hstack([hand, transpose])) == hand_rank,
        twist_singular_values=np.linalg.svd(twist, compute_uv=False) if twist.size else np.zeros(0),
        row_mismatch=float(np.max(np.abs(rows[:, object_columns] - transpose))),
        weight=weight,
        capacity=grasp_capacity(
            analysis.grasp_map, narrowed(geometry, margin) if margin else geometry, weight, squeeze, axes
        ),
    )


@dataclass
class ControlSeries:
    """An object-level controlled run, per recorded sample.

    Attributes:
        t: times [s]. position_error: ``|p - p_desired|`` [m]. orientation_error: ``|log3(R_d^T R)|`` [rad].
        cone_margin: the smallest friction-cone margin over the contacts, ``mu f_n - |f_t|`` [N].
        torques: the controller's joint torques (samples x hand DOF) [N m]. joints: their names.
        effort_limit: the URDF's limits of those joints [N m] (inf where none).
    """

    t: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    cone_margin: np.ndarray
    torques: np.ndarray
    joints: list[str]
    effort_limit: np.ndarray


def control_series(scene: Scene, trajectory: Any, controller: Any) -> ControlSeries:
    """Tracking errors, cone margins and joint torques of a run of ``scene`` driven by ``controller`` (a
    ``grasp-control`` force element of the scene), from the trajectory's samples and multipliers."""
    model = ConstrainedModel(scene)
    kin = model.kin
    rows = trajectory.info.constraint_rows
    forces = trajectory.multipliers
    n = len(trajectory.t)
    position, orientation, margin = np.zeros(n), np.zeros(n), np.full(n, np.inf)
    torques = np.zeros((n, len(controller.hand_columns)))
    for k, (t, q, v) in enumerate(zip(trajectory.t, trajectory.q, trajectory.v, strict=True)):
        kin.update(q, v)
        position[k], orientation[k] = controller.tracking_error(kin.placement(controller.object_frame), float(t))
        torques[k] = controller.generalized_force(kin, v, float(t))[controller.hand_columns]
        for contact in controller.contacts:
            start, stop = rows[contact.name]
            margin[k] = min(margin[k], contact.margins(forces[k, start:stop]).get("friction", np.inf))
    by_column = {scene.model.joints[j].idx_v: scene.model.names[j] for j in range(1, scene.model.njoints)}
    joints = [by_column.get(int(c), f"v[{c}]") for c in controller.hand_columns]
    return ControlSeries(trajectory.t, position, orientation, margin, torques, joints, controller.effort_limit)
