"""The modes of a unilateral contact with Coulomb friction, and the events that switch them.

* ``sticking``: the contact point is held (3 rows: normal and two tangents), its force inside the round
  cone ``|f_t| <= mu f_n``.
* ``sliding``: the normal row only; the friction force is ``-mu f_n d`` with ``d`` the unit slip velocity
  (the unit tangential acceleration when sliding starts from rest), on the boundary of the round cone.
* ``separated``: no rows, no force; the gap may close (an impact).

An impact (*closing*) is not a mode that lasts: it is an instant at which an impulse changes the velocities
(Newton's restitution e on the normal velocity, the tangential impulse inside the cone).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np


class Mode(StrEnum):
    """What a contact does between two events."""

    STICKING = "sticking"
    SLIDING = "sliding"
    SEPARATED = "separated"


CLOSING = "closing"  # the impact between separated and a lasting mode (an event, not a mode)
HOLDING, LET_GO = "holding", "let go"  # a grasp-hold's let-go (an event of a force element, not a contact): from, to


@dataclass(frozen=True)
class ContactEvent:
    """A switch of a contact's mode.

    Attributes:
        t: time [s]. contact: the contact's name. before, after: modes (``closing`` for an impact's
            ``after``... then the mode it settles in). cause: what triggered it (``normal force reached
            zero``, ``friction reached the cone``, ``slip velocity reached zero``, ``gap closed``, ``start``,
            ``impact``, ``at rest``). force: the contact force after the event in the contact frame (normal, t1,
            t2) [N]. slip_velocity: the tangential velocity of the contact point (t1, t2) [m/s]. impulse: the
            impact's impulse (normal, t1, t2) [N s], or None. work: the work of the impact's impulse on this contact
            (or joint limit) [J], ``impulse . (u- + u+) / 2`` with u the contact point's velocity (the limit's rate)
            before and after: the change of kinetic energy it makes (negative: lost), or None.
    """

    t: float
    contact: str
    before: str
    after: str
    cause: str
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    slip_velocity: tuple[float, float] = (0.0, 0.0)
    impulse: tuple[float, float, float] | None = field(default=None)
    work: float | None = None

    def to_dict(self) -> dict:
        """The event as JSON-ready data."""
        data = {
            "t": float(self.t),
            "contact": self.contact,
            "from": self.before,
            "to": self.after,
            "cause": self.cause,
            "force": list(self.force),
            "slip_velocity": list(self.slip_velocity),
        }
        if self.impulse is not None:
            data["impulse"] = list(self.impulse)
        if self.work is not None:
            data["work"] = float(self.work)
        return data


def as_tuple(values: np.ndarray) -> tuple[float, ...]:
    """Plain floats of a small array (for events and JSON)."""
    return tuple(float(x) for x in values)


STOP_KINDS = ("slip", "separation")  # the events a run can be asked to stop at (``stop_on``)
AT_REST = 1e-9  # [m/s] a contact point slower than this along the plane is at rest


def stop_kind(event: ContactEvent) -> str | None:
    """What a lost grasp looks like in an event: ``slip`` (a contact at rest starts sliding: a sticking one
    whose friction reached the cone, or one that slides from rest at the start), ``separation`` (a touching
    contact opens: a sticking or sliding one whose normal force reached zero, or a rebound after an impact),
    or None."""
    if event.after == Mode.SLIDING.value:
        at_rest = event.cause == "start" and float(np.hypot(*event.slip_velocity)) <= AT_REST
        return "slip" if event.before == Mode.STICKING.value or at_rest else None
    if event.after == Mode.SEPARATED.value and event.before != Mode.SEPARATED.value:
        return "separation"
    return None
