"""The contacts along an event-driven run: each contact's mode, point and force at each kept sample.

The modes come from the run's events (``info.contact_events``, :class:`~pinstab.contact.modes.ContactEvent`
as dicts): between two events a contact keeps the mode the first one switched it to (an impact, *closing*,
lasts no time: the event after it, at the same instant, gives the mode it settles in). A sample at time t
is in the mode of the last event at or before t; an event up to :data:`SAMPLE_SLACK` of a step after t
counts too, since the run keeps the state after an event that falls on a grid time at that grid time.

The forces are those of :class:`~pinstab.solvers.contact_modes.ModeDynamics` with the contacts in these
modes at the sample's state, as the run computed them (no Baumgarte gains); a sliding contact whose slip
speed is below :data:`~pinstab.solvers.contact_modes.SLIP_FLOOR` slides in the direction its event's
friction force gave. The contacts' rotational frictions (``<contact> torsion``, ``<contact> rolling`` events) take
their modes the same way; the states list the contacts' own.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..contact.modes import LET_GO, Mode
from ..errors import PinstabError
from ..model import ConstrainedModel
from ..scene import Scene
from ..trajectory import Trajectory
from .contact_modes import ModeDynamics, plane_geometries, spin_name

SAMPLE_SLACK = 1e-9  # [fraction of a step] the grid's slack: an event this close after a sample is at it
MODES = [mode.value for mode in Mode]


@dataclass(frozen=True)
class ModeSpan:
    """An interval in which one contact keeps one mode.

    Attributes:
        contact: the contact's name. mode: ``sticking``, ``sliding`` or ``separated``. start, end: [s] (the
            times of the events that began and ended it, or the run's end). direction: the unit slip direction
            (t1, t2) a sliding span started in (from its event's friction force), else None.
    """

    contact: str
    mode: str
    start: float
    end: float
    direction: tuple[float, float] | None = None


@dataclass(frozen=True)
class ContactStates:
    """Each contact at each sample of a run (k contacts, n samples).

    Attributes:
        names: the contacts (k). t: the sample times (n,) [s]. modes: (n, k) mode names.
        points: (n, k, 3) the contact points [m, world] (a sphere's touching point).
        forces: (n, k, 3) the force of the plane on the body [N, world axes].
        local: (n, k, 3) the same force in each contact's basis (normal, t1, t2) [N].
        normals: (k, 3) the planes' normals (into the body). mu: (k,) friction coefficients [-].
        spans: every contact's mode spans, in time order per contact. impacts: (time [s], contact) of each impact.
    """

    names: list[str]
    t: np.ndarray
    modes: np.ndarray
    points: np.ndarray
    forces: np.ndarray
    local: np.ndarray
    normals: np.ndarray
    mu: np.ndarray
    spans: list[ModeSpan]
    impacts: list[tuple[float, str]]

    @property
    def normal_force(self) -> np.ndarray:
        """(n, k) the normal force of each contact [N] (>= 0 when it pushes)."""
        return self.local[..., 0]

    @property
    def tangential_force(self) -> np.ndarray:
        """(n, k) the magnitude of each contact's friction force [N]."""
        return np.hypot(self.local[..., 1], self.local[..., 2])


def mode_spans(events: list[dict], names: list[str], t_end: float) -> list[ModeSpan]:
    """The mode spans of contacts ``names`` from a run's events (dicts with ``t``, ``contact``, ``to``,
    ``force``; a grasp-hold's let-go skipped), up to ``t_end`` [s]; a new span begins only where the mode changes.

    Raises:
        PinstabError: an event of a contact not in ``names``, or a contact without a ``start`` event.
    """
    opened: dict[str, list[ModeSpan]] = {name: [] for name in names}
    for event in events:
        name, mode = event["contact"], event["to"]
        if mode == LET_GO:  # a grasp-hold's, not a contact's
            continue
        if name not in opened:
            raise PinstabError(f"contact event of {name!r}: no such contact; contacts: {', '.join(names)}")
        if mode not in MODES:  # an impact: the next event, at the same time, settles the mode
            continue
        spans, t = opened[name], float(event["t"])
        if spans and spans[-1].mode == mode:
            continue
        if spans:
            spans[-1] = dataclasses.replace(spans[-1], end=t)
        spans.append(ModeSpan(name, mode, t, t_end, _slip_direction(event) if mode == Mode.SLIDING else None))
    missing = [name for name, spans in opened.items() if not spans]
    if missing:
        raise PinstabError(f"contact {missing[0]!r} has no events: a run with contacts='event' starts each contact")
    return [span for spans in opened.values() for span in spans]


def _slip_direction(event: dict) -> tuple[float, float]:
    """The unit slip direction (t1, t2) opposite the event's friction force ((1, 0) without friction)."""
    friction = -np.asarray(event["force"][1:3], dtype=float)
    size = math.hypot(*friction)
    return (float(friction[0] / size), float(friction[1] / size)) if size > 0 else (1.0, 0.0)


def span_at(spans: list[ModeSpan], time_s: float, slack: float = 0.0) -> ModeSpan:
    """The last of one contact's ``spans`` starting at or before ``time_s + slack`` [s] (its first before them)."""
    current = spans[0]
    for span in spans[1:]:
        if span.start > time_s + slack:
            break
        current = span
    return current


def contact_states(scene: Scene, trajectory: Trajectory) -> ContactStates:
    """Each plane contact's mode, point and force at every sample of ``trajectory``, an event-driven run
    (``simulate(scene, contacts="event")``) of ``scene``; NaN points and forces at non-finite samples.

    Raises:
        PinstabError: a run without contact events, a scene without plane contacts, or a scene and run
            that do not match (configuration size, contact names).
    """
    events = trajectory.info.contact_events
    if not events:
        raise PinstabError(
            f"run of scene {trajectory.info.scene}: no contact events; contact states need a run with contacts='event'"
        )
    geometries = plane_geometries(scene.constraints)
    if not geometries:
        raise PinstabError(f"scene {scene.name} has no plane contacts")
    if trajectory.q.shape[1] != scene.model.nq:
        raise PinstabError(
            f"scene {scene.name} has {scene.model.nq} configuration coordinates, the run {trajectory.q.shape[1]}"
        )
    names = [geometry.name for geometry in geometries]
    dynamics = ModeDynamics(ConstrainedModel(dataclasses.replace(scene, constraints=[])), geometries)
    turning = [spin_name(names[spin.contact], spin) for spin in dynamics.spins]  # their rotational frictions
    spans = mode_spans(events, names + turning, float(trajectory.t[-1]))
    by_contact = {name: [span for span in spans if span.contact == name] for name in names + turning}
    n, k = len(trajectory.t), len(names)
    modes = np.empty((n, k), dtype=object)
    points, forces, local = np.full((n, k, 3), np.nan), np.full((n, k, 3), np.nan), np.full((n, k, 3), np.nan)
    slack = SAMPLE_SLACK * trajectory.info.dt
    for s, (t, q, v) in enumerate(zip(trajectory.t, trajectory.q, trajectory.v, strict=True)):
        current = [span_at(by_contact[name], float(t), slack) for name in names]
        modes[s] = [span.mode for span in current]
        if not (np.isfinite(q).all() and np.isfinite(v).all()):
            continue
        spins = [span_at(by_contact[name], float(t), slack) for name in turning]
        for f, span in enumerate(current + spins):
            if span.direction is not None:
                dynamics.directions[f] = np.array(span.direction[: dynamics.frictions[f].rows.size])
        sliding = [Mode.SLIDING if span.mode == Mode.SLIDING else Mode.STICKING for span in spins]
        solution = dynamics.solve(q, v, float(t), [Mode(span.mode) for span in current], sliding)
        points[s], local[s] = solution.contacts.positions, solution.forces
        forces[s] = np.einsum("kij,ki->kj", np.array([g.basis for g in geometries]), solution.forces)
    impacts = [(float(e["t"]), e["contact"]) for e in events if e["to"] not in MODES]
    return ContactStates(
        names,
        trajectory.t.copy(),
        modes,
        points,
        forces,
        local,
        np.array([g.basis[0] for g in geometries]),
        np.array([g.mu for g in geometries]),
        spans,
        impacts,
    )
