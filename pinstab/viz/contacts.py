"""Contact forces drawn over a recording: per contact an arrow for the force on the object (or on the
body of a plane contact), and a translucent friction cone per friction contact.

The arrow ends at the contact point and comes from the side of what pushes (the finger, the plane): a
pushing force sits inside the cone, which opens outward from the contact point with half-angle
atan(mu). Its length is ``|f| / scale``, one scale [N/m] for the whole recording, chosen so that the
largest force of the recorded frames is :data:`FORCE_FRACTION` of the scene's size. Its colour runs
from green (along the normal) to amber (on the cone's surface), red outside the cone or pulling;
arrows are drawn over everything, so that they show through the fingertip and the object.
The forces at a frame's time are the trajectory's multipliers interpolated with the weights that
:func:`~pinstab.trajectory.configurations_at` gives the configurations.

A run with event-driven contacts (``simulate(scene, contacts="event")``) has no multipliers: its forces are
the contact states of :func:`~pinstab.solvers.contact_states.contact_states` (interpolated the same way),
and its contacts show their modes: a sphere at each contact point and the arrow take the mode's colour
(:data:`MODE_COLORS`: sticking blue, sliding orange, separated grey; the mode at the frame's exact time,
from the events). Its scale is the scene's weight: an arrow of m |g| is FORCE_FRACTION of the scene's size.
"""

from __future__ import annotations

import math
from typing import Protocol

import meshcat.geometry as mg
import numpy as np
import pinocchio as pin

from ..constraints import PointContact
from ..constraints.contacts import contact_basis
from ..constraints.grasp_contacts import FingertipContact
from ..contact.models import FRICTION_MODELS
from ..kinematics import Kinematics
from ..model import ConstrainedModel
from ..solvers.contact_states import ModeSpan, contact_states, span_at
from ..trajectory import Trajectory, sample_weights
from .nodes import ROOT, Y_AXIS, rotation_onto, set_color, set_pose

FORCE_FRACTION = 0.5  # the largest force is drawn this fraction of the scene's size long
# arrow and cone sizes, as fractions of the longest arrow: shaft and head radius, head length, cone side
SHAFT_RADIUS, HEAD_RADIUS, HEAD_LENGTH, CONE_SLANT = 0.03, 0.075, 0.2, 0.5
CONE_OPACITY = 0.3
USAGE_SLACK = 1e-9  # a force this little past the cone's surface (relative) still counts as on it
GREEN, AMBER, RED = np.array([0.1, 0.8, 0.25]), np.array([1.0, 0.7, 0.0]), (0.9, 0.1, 0.1)
# the colours of the contact modes (event-driven runs): points and arrows
MODE_COLORS = {"sticking": (0.1, 0.35, 0.95), "sliding": (1.0, 0.5, 0.0), "separated": (0.55, 0.55, 0.55)}
POINT_RADIUS = 0.06  # a contact point's sphere, as a fraction of the longest arrow
TINY = 1e-9  # scale of a zero-length arrow part (three.js needs an invertible matrix)
# turns a cone built along y (apex at +y) so that y is the contact's z axis (the normal into the object)
Y_TO_Z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


class ContactView(Protocol):
    """What the overlay draws of one contact constraint block.

    Attributes:
        name: the constraint's name. mu: its friction coefficient, None without a friction cone.
    """

    name: str
    mu: float | None

    def frame(self, kin: Kinematics) -> pin.SE3:
        """The contact frame in the world: origin at the contact point [m], z the normal into the object."""

    def force(self, block: np.ndarray) -> np.ndarray:
        """(f_x, f_y, f_n) [N]: the block's multipliers as the force on the object in the contact frame."""

    def usage(self, block: np.ndarray) -> float:
        """Fraction of its friction cone the force uses: 0 along the normal, 1 on the surface, inf pulling."""


def _ratio(load: float, capacity: float) -> float:
    return load / capacity if capacity > 0 else (0.0 if load == 0 else math.inf)


def _usage(normal: float, pairs: list[tuple[float, float]]) -> float:
    """Largest load / capacity of (load, capacity) pairs [N or N m]; inf when ``normal`` [N] pulls (or is NaN)."""
    if not normal >= 0:
        return math.inf
    return max((_ratio(load, capacity) for load, capacity in pairs), default=0.0)


class GraspView:
    """A fingertip contact: the force of the finger on the object, the cone about the object's normal."""

    def __init__(self, contact: FingertipContact) -> None:
        self.contact, self.name = contact, contact.name
        self.mu = contact.mu if contact.model in FRICTION_MODELS else None

    def frame(self, kin: Kinematics) -> pin.SE3:
        return kin.placement(self.contact.object_frame)

    def force(self, block: np.ndarray) -> np.ndarray:
        return self.contact.wrench(block)[:3]

    def usage(self, block: np.ndarray) -> float:
        contact = self.contact
        if contact.model == "rigid":
            return 0.0
        wrench = contact.wrench(block)
        pairs = [(math.hypot(wrench[0], wrench[1]), contact.mu * wrench[2])] if self.mu is not None else []
        if contact.model == "soft-finger":
            pairs.append((abs(wrench[5]), contact.torsion * wrench[2]))
        return _usage(float(wrench[2]), pairs)


class PlaneView:
    """A body point on a plane: the plane's force on the body, the cone about the plane's normal."""

    def __init__(self, contact: PointContact) -> None:
        self.contact, self.name = contact, contact.name
        self.mu = None if contact.friction is None else contact.friction.mu
        normal, tangent_1, tangent_2 = contact_basis(contact.selection[0])
        self.rotation = np.column_stack([tangent_1, tangent_2, normal])

    def frame(self, kin: Kinematics) -> pin.SE3:
        """At the contact point: the frame's origin, or a sphere's lowest point along the normal."""
        centre = kin.placement(self.contact.frame_a).translation
        return pin.SE3(self.rotation, centre - self.contact.radius * self.rotation[:, 2])

    def force(self, block: np.ndarray) -> np.ndarray:
        return np.array([block[1], block[2], block[0]]) if len(block) == 3 else np.array([0.0, 0.0, block[0]])

    def usage(self, block: np.ndarray) -> float:
        force = self.force(block)
        pairs = [(math.hypot(force[0], force[1]), self.mu * force[2])] if self.mu is not None else []
        return _usage(float(force[2]), pairs)


def contact_views(model: ConstrainedModel) -> list[ContactView]:
    """The grasp and plane contacts of ``model``, in constraint order."""
    views: list[ContactView] = []
    for constraint in model.constraints.constraints:
        if isinstance(constraint, FingertipContact):
            views.append(GraspView(constraint))
        elif isinstance(constraint, PointContact):
            views.append(PlaneView(constraint))
    return views


def sample_at(t: np.ndarray, values: np.ndarray, time_s: float) -> np.ndarray:
    """Row of ``values`` (one per sample time ``t`` [s]) at ``time_s`` [s]: linear between samples, held
    at the ends (the weights :func:`~pinstab.trajectory.configurations_at` uses)."""
    if len(t) < 2:
        return values[0]
    k, u = sample_weights(t, time_s)
    return (1.0 - u) * values[k] + u * values[k + 1]


def _arrow_material() -> mg.MeshLambertMaterial:
    """Drawn over everything (no depth test; as a transparent material, after the opaque meshes), so that
    an arrow shows through the fingertip and the object it points into."""
    return mg.MeshLambertMaterial(color=0x1ACC40, opacity=1.0, transparent=True, depthTest=False)


def usage_color(usage: float) -> tuple[float, float, float]:
    """Green at 0 (along the normal) to amber at 1 (on the friction cone), red beyond or unknown (NaN)."""
    if not usage <= 1.0 + USAGE_SLACK:
        return RED
    red, green, blue = GREEN + min(max(usage, 0.0), 1.0) * (AMBER - GREEN)
    return (float(red), float(green), float(blue))


class ContactForces:
    """The overlay: an arrow per contact and a cone per friction contact (see the module's docstring).

    Args:
        model: the constrained model. trajectory: its run (multipliers, rows per block).
        times: the frame times [s] (the scale fits the largest force among them). size: the scene's size [m].

    Attributes:
        scale: newtons per metre of arrow [N/m] (an arrow is ``|f| / scale`` long); None without contacts.
        spans: with event-driven contacts, each contact's mode spans (else empty).
    """

    def __init__(self, model: ConstrainedModel, trajectory: Trajectory, times: np.ndarray, size: float) -> None:
        self.kin, self.longest = model.kin, FORCE_FRACTION * size
        rows = trajectory.info.constraint_rows
        self.views = contact_views(model)
        self.scale: float | None = None
        self.spans: dict[str, list[ModeSpan]] = {}
        if not self.views:
            return
        self.t = trajectory.t
        reference = math.nan  # [N] the force drawn FORCE_FRACTION x size long
        if trajectory.info.contact_events:
            states = contact_states(model.scene, trajectory)
            self.multipliers = states.local.reshape(len(states.t), -1)
            self.rows = {name: slice(3 * i, 3 * i + 3) for i, name in enumerate(states.names)}
            self.spans = {name: [span for span in states.spans if span.contact == name] for name in states.names}
            reference = pin.computeTotalMass(model.model) * float(np.linalg.norm(model.model.gravity.linear))
        else:
            self.views = [view for view in self.views if view.name in rows]  # those the run has multipliers of
            self.multipliers = trajectory.multipliers
            self.rows = {view.name: slice(*rows[view.name]) for view in self.views}
        if not reference > 0:  # the largest force of the frames
            magnitudes = [np.linalg.norm(view.force(block)) for t in times for view, block in self._blocks(float(t))]
            reference = float(np.nanmax(magnitudes, initial=0.0))
        self.scale = (reference if math.isfinite(reference) and reference > 0 else 1.0) / self.longest

    def _blocks(self, time_s: float) -> list[tuple[ContactView, np.ndarray]]:
        """Every contact with its multipliers at ``time_s`` [s]."""
        row = sample_at(self.t, self.multipliers, time_s)
        return [(view, row[self.rows[view.name]]) for view in self.views]

    def _cone_height(self, view: ContactView) -> float:
        """[m] of the cone with side CONE_SLANT x the longest arrow and half-angle atan(mu)."""
        return CONE_SLANT * self.longest * math.cos(math.atan(view.mu))

    @staticmethod
    def path(name: str, part: str) -> str:
        """Viewer path of a contact's ``arrow``, ``arrow/shaft``, ``arrow/head``, ``cone`` or ``point``."""
        return f"{ROOT}/contacts/{name}/{part}"

    def load(self, viewer) -> None:
        longest = self.longest
        for view in self.views:
            for part, shape in (
                ("arrow/shaft", mg.Cylinder(1.0, SHAFT_RADIUS * longest)),
                ("arrow/head", mg.Cylinder(HEAD_LENGTH * longest, radiusTop=0.0, radiusBottom=HEAD_RADIUS * longest)),
            ):
                viewer[self.path(view.name, part)].set_object(shape, _arrow_material())
            if self.spans:
                viewer[self.path(view.name, "point")].set_object(mg.Sphere(POINT_RADIUS * longest), _arrow_material())
            if view.mu is not None:
                height = self._cone_height(view)
                material = mg.MeshLambertMaterial(color=0xF2F2FF, opacity=CONE_OPACITY, transparent=True)
                viewer[self.path(view.name, "cone")].set_object(
                    mg.Cylinder(height, radiusTop=0.0, radiusBottom=height * view.mu), material
                )

    def update(self, frame, q: np.ndarray, t: float) -> None:
        if not self.views:
            return
        self.kin.update_positions(q)
        for view, block in self._blocks(t):
            contact = view.frame(self.kin)
            if self.spans:
                color = MODE_COLORS[span_at(self.spans[view.name], t).mode]
                set_pose(frame[self.path(view.name, "point")], pin.SE3(np.eye(3), contact.translation))
                set_color(frame[self.path(view.name, "point")], color, 1.0)
            else:
                color = usage_color(view.usage(block))
            self._arrow(frame, view.name, contact, view.force(block), color)
            if view.mu is not None:
                apex_at_origin = pin.SE3(Y_TO_Z, Y_TO_Z @ np.array([0.0, -self._cone_height(view) / 2, 0.0]))
                set_pose(frame[self.path(view.name, "cone")], contact * apex_at_origin)

    def _arrow(self, frame, name: str, contact: pin.SE3, force: np.ndarray, color: tuple[float, float, float]) -> None:
        """Arrow along ``force`` [N] (contact frame axes) ending at the contact point, |f| / scale [m] long."""
        magnitude = float(np.linalg.norm(force))
        if not math.isfinite(magnitude):
            magnitude, force = 0.0, np.zeros(3)
        direction = contact.rotation @ (force / magnitude if magnitude > 0 else np.array([0.0, 0.0, 1.0]))
        length = magnitude / self.scale
        head_full = HEAD_LENGTH * self.longest
        head = min(head_full, length)
        shaft = length - head
        set_pose(frame[self.path(name, "arrow")], pin.SE3(rotation_onto(Y_AXIS, direction), contact.translation))
        set_pose(
            frame[self.path(name, "arrow/head")],
            pin.SE3(np.eye(3), np.array([0.0, -head / 2, 0.0])),
            (max(head / head_full, TINY),) * 3,
        )
        set_pose(
            frame[self.path(name, "arrow/shaft")],
            pin.SE3(np.eye(3), np.array([0.0, -head - shaft / 2, 0.0])),
            (1.0, max(shaft, TINY), 1.0),
        )
        for part in ("arrow/head", "arrow/shaft"):
            set_color(frame[self.path(name, part)], color, 1.0)
