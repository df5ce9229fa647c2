"""Sticking fingertip contacts on a scene object [MLS ch. 5] (docs/mathematics.md section 4).

Kind ``grasp-contact``: the fingertip is a sphere of ``radius`` [m] centred at the ``finger`` frame's
origin, touching ``object`` (a scene object). At the scene's start the finger's joints are moved (least
change, Gauss-Newton on the signed distance; the object stays put) until the sphere touches the object's
surface; the contact frame C sits at the touching point, its z axis the normal into the object, and
from then on the contact holds that material point of the object on that material point of the
fingertip. The contact ``model`` picks the rows, the wrench components C transmits:

* ``frictionless`` 1 row: the normal; ``point-friction`` 3: the point; ``soft-finger`` 4: the point and
  the spin about the normal; ``rigid`` 6: the point and the relative rotation.

Rows: ``R_C^T (p_o - p_f)`` (C's axes, p_o on the object, p_f on the fingertip) then
``log3(R_f^T R_o)`` of the two frames that coincide with C at the start. The multipliers are the force
[N] and moment [N m] of the finger on the object in C (the finger receives the opposite). They are
equality rows; every solve checks that the contact only pushes (normal force >= 0) and stays inside its
friction cone (|f_t| <= mu f_n, soft finger also |m_z| <= torsion f_n), else
:class:`~pinstab.errors.GraspLostError` names the contact and the time.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from ..contact.coefficients import friction_coefficient
from ..contact.collisions import Touch
from ..contact.models import CONTACT_MODEL_CODES, FRICTION_MODELS, WRENCH_BASES, ContactLimits
from ..contact.objects import Nearest, nearest_shape
from ..errors import SceneError, choices
from ..kernels import RowBlock, block_drift, block_jacobian, block_residual, contact_point_residual
from ..kinematics import Kinematics, PerUpdate, frame_jacobian
from ..memory import new_data
from ..tables import SceneTables
from .base import CONSTRAINT_KINDS, Constraint, VelocityTerms
from .contacts import friction_length
from .loops import plane_basis

GRASP_KEYS = {"name", "kind", "finger", "object", "model", "radius", "mu", "torsion", "surface"}
SURFACES = ("plane", "round")  # event-driven grasp contacts: the tangent plane at C, or both spheres' surfaces
GAP_TOLERANCE = 1e-10  # [m] a fingertip this close to the surface touches it
GAP_ITERATIONS = 60


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of 3-vectors (np.cross costs more than the rest of a contact's drift; so does indexing the arrays)."""
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


class FingertipContact(Constraint):
    """A sticking contact of a fingertip on an object, the rows of its contact model.

    Args:
        name: unique name. model: a key of :data:`~pinstab.contact.models.WRENCH_BASES`.
        object_frame: operational frame on the object at C. finger_frame: operational frame on the
            fingertip, coinciding with C at the start. object_name, finger_name: for messages.
        mu: friction coefficient [-]. torsion: the soft finger's torsional coefficient [m].
        radius: the fingertip sphere's radius [m].
    """

    holonomic = True

    def __init__(
        self,
        name: str,
        model: str,
        object_frame: int,
        finger_frame: int,
        object_name: str,
        finger_name: str,
        mu: float = 0.0,
        torsion: float = 0.0,
        radius: float = 0.0,
    ) -> None:
        self.name, self.kind, self.model = name, "grasp-contact", model
        self.object_frame, self.finger_frame = object_frame, finger_frame
        self.object_name, self.finger_name = object_name, finger_name
        self.mu, self.torsion, self.radius = mu, torsion, radius
        self.round: RoundGrasp | None = None  # event-driven contacts on both spheres' surfaces (surface = "round")
        self.limits = ContactLimits(name, model, mu, torsion, finger_name, object_name)
        self.touch = Touch(name, finger_frame, object_frame, at_point=True)
        self.components = np.flatnonzero(WRENCH_BASES[model].any(axis=1))  # of (fx, fy, fz, mx, my, mz) in C
        self.rows = len(self.components)
        self.limits_force = model != "rigid"
        self.angular = bool(self.components[-1] >= 3)
        # the rows in the compiled core (cpp/core_rows.cpp): the point's, then a weld's rotation rows between the
        # object's and the finger's copy of C, the model's components of them
        self.block = RowBlock(5, object_frame, finger_frame, np.eye(4), np.zeros((0, 3)))
        self.block.set_contact(self.components.astype(np.int32), CONTACT_MODEL_CODES[model], mu, torsion)
        self.force_frame = "contact frame C (x, y tangents, z normal into the object), force/moment of finger on object"
        # the constraint stack, a grasp force element and a grasp controller read them at the same state
        self._points = PerUpdate(self._compute_point_residual)
        self._velocity_terms = PerUpdate(self._compute_velocity_terms)
        self._drift = PerUpdate(self._compute_drift)

    # -- rows ----------------------------------------------------------------------------------------
    def _point_residual(self, kin: Kinematics) -> np.ndarray:
        """R_C^T (p_o - p_f) [m]: the material points' difference in C (shared: not to be modified)."""
        return self._points(kin)

    def _compute_point_residual(self, kin: Kinematics) -> np.ndarray:
        # compiled: cpp/contact_terms.cpp
        return contact_point_residual(kin.model, kin.data, self.object_frame, self.finger_frame)

    def compiled_rows(self) -> RowBlock:
        return self.block

    def residual(self, kin: Kinematics, q: np.ndarray, t: float) -> np.ndarray:
        return block_residual(kin.model, kin.data, self.block, q, t)

    def velocity_terms(self, kin: Kinematics, q: np.ndarray, t: float) -> VelocityTerms:
        return self._velocity_terms(kin)

    def drift(self, kin: Kinematics, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """gamma0 at ``kin``'s state (``v`` is the velocity of its last full update)."""
        return self._drift(kin)

    def _compute_velocity_terms(self, kin: Kinematics) -> VelocityTerms:
        # d/dt R^T d = R^T (v_o - v_f) + R^T [d]x omega_o, and the weld's rotation rows (cpp/core_rows.cpp)
        return VelocityTerms(*block_jacobian(kin.model, kin.data, self.block, 0.0))

    def _compute_drift(self, kin: Kinematics) -> np.ndarray:
        # d2/dt2 R^T d at zero joint acceleration: R^T (a_o - a_f + w x (w x d - 2 d') - alpha x d) (compiled)
        return block_drift(kin.model, kin.data, self.block, 0.0)

    # -- forces --------------------------------------------------------------------------------------
    def wrench(self, force: np.ndarray) -> np.ndarray:
        """The contact's multipliers as the full wrench (fx, fy, fz, mx, my, mz) in C [N, N m]."""
        full = np.zeros(6)
        full[self.components] = force
        return full

    def margins(self, force: np.ndarray) -> dict[str, float]:
        """How far the contact force (this block's multipliers) is inside what the contact can carry
        (:meth:`~pinstab.contact.models.ContactLimits.margins`); a rigid contact carries anything (no margins)."""
        return self.limits.margins(self.wrench(force))

    def check_force(self, force: np.ndarray, t: float) -> None:
        """Raise :class:`GraspLostError` when the contact would have to pull, slide or spin."""
        self.limits.check(self.wrench(force), t)

    def slip(self, kin: Kinematics) -> float | None:
        """Distance between the contact's material points on the object and on the fingertip [m] (the
        creep of a sticking contact); None for a frictionless contact, which may slide. Placements must
        be current."""
        if self.model == "frictionless":
            return None
        return float(np.linalg.norm(self._point_residual(kin)))


# -- scene table ---------------------------------------------------------------------------------------
class Fingertip(NamedTuple):
    """A contact's fingertip sphere and the object it touches, as its scene table gives them.

    Attributes:
        frame: the frame at the sphere's centre. name: that frame's name in the table. radius: [m].
        item: the scene object (a :class:`~pinstab.contact.objects.SceneObject`, with contact geometries).
    """

    frame: int
    name: str
    radius: float
    item: Any


def close_gap(tables: SceneTables, fingertip: Fingertip, where: str) -> Nearest:
    """Move the finger's joints (not the object, not joints an earlier contact placed) in ``tables.q0``
    until the fingertip sphere touches the object; the nearest shape at the touching configuration.

    Raises:
        SceneError: the finger's own joints cannot close the gap (named by ``where``).
    """
    model, q, frame, item = tables.model, tables.q0, fingertip.frame, fingertip.item
    joints = [j for j in model.supports[model.frames[frame].parentJoint] if j > 0]
    free = [j for j in joints if j not in tables.claimed_joints]
    columns = [k for j in free for k in range(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv)]
    sphere = coal.Sphere(fingertip.radius)
    data = new_data(model)
    for _ in range(GAP_ITERATIONS):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        nearest = nearest_shape(sphere, data.oMf[frame].translation, item, data.oMf[item.frame])
        gap = nearest.distance
        if abs(gap) <= GAP_TOLERANCE or not columns:
            break
        row = -nearest.normal @ frame_jacobian(model, data, frame)[:3]
        step = np.zeros(model.nv)
        sub = row[columns]
        if float(sub @ sub) < 1e-24:
            break
        step[columns] = -sub * gap / float(sub @ sub)
        q[:] = pin.integrate(model, q, step)
    if abs(gap) > 10.0 * GAP_TOLERANCE:
        claimed = sorted({tables.claimed_joints[j] for j in joints if j in tables.claimed_joints})
        reason = (
            f"joints {', '.join(model.names[j] for j in free)} cannot close it"
            if columns
            else "no joint of its own moves the fingertip"
            + (f" (contacts {', '.join(claimed)} placed the shared ones)" if claimed else "")
        )
        raise SceneError(
            f"{where}: fingertip {fingertip.name!r} cannot reach object {item.name!r}: a gap of {gap:.4g} m remains "
            f"at the start ({reason}); change initial.q or the object's position"
        )
    for j in free:
        tables.claimed_joints[j] = where
    return nearest


def read_fingertip(entry: dict, tables: SceneTables, where: str) -> Fingertip:
    """A contact table's ``object`` (a scene object with contact geometry), ``finger`` (a frame at the
    fingertip sphere's centre, not on the object) and ``radius`` [m] (> 0)."""
    objects = tables.objects
    if not isinstance(entry.get("object"), str) or entry["object"] not in objects:
        bodies = f"; {entry.get('object')!r} is a body of the robot, not an object" if _is_frame(tables, entry) else ""
        raise SceneError(
            f"{where}.object: {entry.get('object')!r} is not an object of the scene{bodies}; objects: "
            f"{choices(objects)} (declare one in [[objects]])"
        )
    item = objects[entry["object"]]
    if not item.geometries:
        raise SceneError(f"{where}.object: object {item.name!r} has no collision geometry for a fingertip to touch")
    if "finger" not in entry:
        raise SceneError(f"{where}: 'finger' (the frame at the fingertip sphere's centre) is required")
    finger = tables.frame_id(entry["finger"], f"{where}.finger")
    if tables.model.frames[finger].parentJoint == item.joint:
        raise SceneError(f"{where}.finger: frame {entry['finger']!r} is on object {item.name!r} itself")
    if "radius" not in entry:
        raise SceneError(f"{where}: 'radius' (the fingertip sphere's radius, > 0) is required")
    radius = tables.quantity(entry["radius"], "length", f"{where}.radius")
    if not radius > 0:
        raise SceneError(f"{where}.radius must be > 0, got {entry['radius']!r}")
    tables.within_reach(radius, f"{where}.radius")
    return Fingertip(finger, str(entry["finger"]), radius, item)


def read_coefficients(entry: dict, tables: SceneTables, model_name: str, where: str) -> tuple[float, float]:
    """(mu [-], torsion [m]) of a contact ``model_name``: ``mu`` for ``point-friction`` / ``soft-finger``
    (:func:`~pinstab.contact.coefficients.friction_coefficient`), ``torsion`` >= 0 for ``soft-finger`` (a length on
    the fingertip, :meth:`~pinstab.tables.SceneTables.within_reach`), each refused on a model that takes none."""
    mu = torsion = 0.0
    if _takes(entry, "mu", model_name in FRICTION_MODELS, model_name, where):
        mu = friction_coefficient(entry["mu"], f"{where}.mu")
    if _takes(entry, "torsion", model_name == "soft-finger", model_name, where):
        torsion = friction_length(entry, "torsion", tables, where)
    return mu, torsion


class RoundGrasp(NamedTuple):
    """A grasp contact that event-driven contacts treat as a round pair (:mod:`~pinstab.contact.round_pairs`): the
    fingertip sphere (its centre's frame ``tip_frame``) against a sphere object (its centre ``centre`` [m] in the
    object's body frame ``object_frame``, radius ``radius`` [m]); ``normal``: the unit normal from the object's centre
    towards the fingertip at the start (in the object frame's axes), whose tangents the contact's turn from."""

    tip_frame: int
    object_frame: int
    centre: np.ndarray
    radius: float
    normal: np.ndarray


def round_grasp(entry: dict, tables: SceneTables, fingertip: Fingertip, where: str) -> RoundGrasp | None:
    """The entry's ``surface``: ``plane`` (default: the tangent plane at C, carried by the object) or ``round`` (the
    fingertip sphere on a sphere object's surface, re-computed at every state, so that it may slide over and leave
    it), or None for ``plane``.

    Raises:
        SceneError: another value, or ``round`` on an object that is not one sphere (naming its shapes).
    """
    surface = entry.get("surface", "plane")
    if surface not in SURFACES:
        raise SceneError(f"{where}.surface: unknown surface {surface!r}; surfaces: {choices(SURFACES)}")
    if surface == "plane":
        return None
    item = fingertip.item
    shapes = [type(shape).__name__ for shape, _ in item.geometries]
    if shapes != ["Sphere"]:
        raise SceneError(
            f"{where}.surface: 'round' takes an object that is one sphere; object {item.name!r} has shapes "
            f"{', '.join(shapes) or 'none'}; use surface 'plane'"
        )
    shape, local = item.geometries[0]
    placed = tables.initial_placement(item.frame)
    outward = placed.actInv(tables.initial_placement(fingertip.frame).translation) - local.translation
    return RoundGrasp(
        fingertip.frame, item.frame, local.translation.copy(), float(shape.radius), outward / np.linalg.norm(outward)
    )


def parse_grasp_contact(entry: dict, tables: SceneTables, name: str, where: str) -> FingertipContact:
    """Scene table: ``finger`` (a frame at the fingertip sphere's centre), ``object`` (a scene object),
    ``model`` (default ``point-friction``), ``radius`` [m] of the fingertip sphere, ``mu`` for
    ``point-friction`` / ``soft-finger``, ``torsion`` [m] for ``soft-finger``, ``surface`` (event-driven contacts:
    ``plane`` or ``round``, :func:`round_grasp`)."""
    tables.check_keys(entry, GRASP_KEYS, where)
    model_name = entry.get("model", "point-friction")
    if not isinstance(model_name, str) or model_name not in WRENCH_BASES:
        raise SceneError(f"{where}: unknown contact model {model_name!r}; models: {choices(WRENCH_BASES)}")
    fingertip = read_fingertip(entry, tables, where)
    mu, torsion = read_coefficients(entry, tables, model_name, where)
    normal = close_gap(tables, fingertip, where).normal
    centre = tables.initial_placement(fingertip.frame).translation
    rotation = np.column_stack([*plane_basis(normal), normal])  # x, y tangents, z the inward normal
    contact = pin.SE3(rotation, centre + fingertip.radius * normal)
    object_frame = _frame_at(tables, fingertip.item.frame, contact, f"{name}/object")
    finger_frame = _frame_at(tables, fingertip.frame, contact, f"{name}/finger")
    contact = FingertipContact(
        name, model_name, object_frame, finger_frame, fingertip.item.name, fingertip.name, mu, torsion, fingertip.radius
    )
    contact.round = round_grasp(entry, tables, fingertip, where)
    return contact


def _is_frame(tables: SceneTables, entry: dict) -> bool:
    name = entry.get("object")
    return isinstance(name, str) and tables.model.existFrame(name)


def _takes(entry: dict, key: str, needed: bool, model_name: str, where: str) -> bool:
    """Whether the contact model takes ``key`` (then the entry must give it); refused when it takes none."""
    if not needed and key in entry:
        raise SceneError(f"{where}: a {model_name!r} contact takes no {key!r}")
    if needed and key not in entry:
        raise SceneError(f"{where}: a {model_name!r} contact needs {key!r} (>= 0)")
    return needed


def _frame_at(tables: SceneTables, parent: int, world: pin.SE3, name: str) -> int:
    """An operational frame on ``parent``'s body at the world placement ``world`` (at the start)."""
    local = tables.initial_placement(parent).actInv(world)
    frame = tables.model.frames[parent]
    return tables.model.addFrame(
        pin.Frame(name, frame.parentJoint, parent, frame.placement * local, pin.FrameType.OP_FRAME)
    )


CONSTRAINT_KINDS.register(
    "grasp-contact",
    parse_grasp_contact,
    summary="a fingertip sphere sticking on an object: frictionless 1, point-friction 3, soft-finger 4, rigid 6 rows",
)
