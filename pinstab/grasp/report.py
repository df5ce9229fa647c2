"""A scene's grasps analysed at its assembled start: per object, its fingertip contacts, the grasp map,
the hand Jacobian, their ranks, manipulability, force closure, internal forces and quality
(``pinstab grasp SCENE``).

Frames and units: O is the object's body frame, C_i contact i's frame (z the normal into the object).
G takes the contact forces [N, N m] in their C_i to the object wrench in O [N, N m]; J_h takes the hand's
joint rates [rad/s or m/s] to the fingertip velocities in the C_i [m/s, rad/s], so that the contacts hold
when ``J_h theta_dot = G^T x_dot`` (x_dot the object's body twist, linear first) [MLS ch. 5].
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..assembly import assemble
from ..errors import PinstabError, choices
from ..model import ConstrainedModel
from ..scene import Scene
from .analysis import RANK_TOLERANCE, GraspAnalysis, GraspContact, analyse_grasp
from .hold import contact_rows

FRAMES = {
    "grasp_map": "contact forces in C_i [N, N m] -> object wrench in O [N, N m]",
    "hand_jacobian": "hand joint rates [rad/s, m/s] -> fingertip velocities in C_i [m/s, rad/s]",
    "internal_forces": "contact forces in C_i [N, N m] (unit columns) that load the object without moving it",
    "quality": "Ferrari-Canny epsilon [N]: moments divided by the length, unit total normal force",
    "object_twist_singular_values": "object twist (O, linear first) [m/s, rad/s] per unit joint rate",
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
            "grasp_map": analysis.grasp_map.tolist(),
            "frames": FRAMES,
        }


def analyse_scene_grasps(scene: Scene, facets: int = 8) -> dict[str, ObjectGrasp]:
    """Every grasped object's :class:`ObjectGrasp` at the scene's assembled start, cones linearized with
    ``facets`` sides.

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
    model = ConstrainedModel(scene)
    start = assemble(model, scene.q0, scene.v0)
    model.kin.update_jacobians(start.q)
    return {name: _object_grasp(model, name, contacts, facets) for name, contacts in grasped.items()}


def _object_grasp(model: ConstrainedModel, name: str, contacts: list[Any], facets: int) -> ObjectGrasp:
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
    )


@dataclass
class ControlSeries:
    """An object-level controlled run, per recorded sample.

    Attributes:
        t: times [s]. position_error: |p - p_desired| [m]. orientation_error: |log3(R_d^T R)| [rad].
        cone_margin: the smallest friction-cone margin over the contacts, mu f_n - |f_t| [N].
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
