"""Which contact treatment a run takes: what it is asked for (``simulate(contacts=...)``, ``--contacts``, the scene's
``[run] contacts``), else chosen from the scene's contacts (:func:`contact_choice`), and reported in the run's JSON
(``info.contact_treatment``: treatment, how it was chosen and why).

The choice: a scene whose contacts can switch switches by default; holding them rigid is asked for. Contacts with
event-driven modes (plane contacts, contacts found from geometry, grasp contacts but rigid ones) are ``event`` when
they are the scene's only constraints and at most :data:`MAX_EVENT_CONTACTS` are declared (contacts found from geometry
always: the touching ones are few of those found), ``stepping`` (time-stepping, whose cost does not grow with the
events; torsion included) when more plane contacts are declared, unless some has rolling resistance (event-driven
only); ``held`` (constraint rows) otherwise, naming the
constraint that keeps the modes off. A scene with joint friction (:mod:`pinstab.forces.joint_friction`, stick and slip
at events) is ``event`` unless asked otherwise (by the caller or by its ``[run] contacts``), and refused by a treatment
that cannot take it (:func:`resolve_contacts`). ``simulate(scene)`` (``contacts=None``, the call's default, or
``"auto"``) and ``pinstab run`` without ``--contacts`` take the same choice."""

from __future__ import annotations

from typing import Any, NamedTuple

from ..constraints import FingertipContact, PointContact
from ..errors import PinstabError
from ..forces.joint_friction import joint_frictions, refusal
from ..scene import CONTACT_TREATMENTS, Scene
from ..solvers.contact_modes import modeless_contacts, plane_geometries, rolling_contacts

MAX_EVENT_CONTACTS = 8  # declared plane contacts beyond this many default to time-stepping


class ContactChoice(NamedTuple):
    """A run's contact treatment: ``treatment`` (``held``, ``event`` or ``stepping``), ``chosen`` (``asked``: by the
    caller; ``scene``: by its ``[run] contacts``; ``automatic``: :func:`contact_choice`) and ``why`` (words)."""

    treatment: str
    chosen: str
    why: str

    def summary(self) -> dict[str, Any]:
        """The choice as the run's JSON reports it (``info.contact_treatment``)."""
        return self._asdict()


def contact_choice(scene: Scene) -> ContactChoice | None:
    """The treatment a run of ``scene`` takes unless asked for one (module docstring), or None for a scene without
    contacts."""
    contacts = [c for c in scene.constraints if isinstance(c, PointContact | FingertipContact)]
    frictions = joint_frictions(scene.forces)
    if not contacts and not frictions:
        return None
    if scene.contacts is not None:
        return ContactChoice(scene.contacts, "scene", f"scene {scene.name} asks for it ([run] contacts)")
    if frictions:
        names = ", ".join(friction.name for friction in frictions)
        return ContactChoice("event", "automatic", f"joint frictions {names}: stick and slip at events")
    others = [c.name for c in scene.constraints if not isinstance(c, PointContact | FingertipContact)]
    if others:
        return ContactChoice("held", "automatic", f"constraints {', '.join(others)} are not contacts")
    modeless = modeless_contacts(contacts)
    if modeless:
        first = modeless[0]
        return ContactChoice("held", "automatic", f"grasp contact {first.name} is {first.model}: no event-driven modes")
    geometries = plane_geometries(contacts)
    count = len(contacts)
    if scene.contact_finders:
        return ContactChoice("event", "automatic", f"{count} contacts found from geometry, each with modes")
    rolling = rolling_contacts(geometries)
    if count > MAX_EVENT_CONTACTS and rolling:
        return ContactChoice(
            "event", "automatic", f"{count} contacts, rolling resistance at {rolling[0]}: time-stepping has none"
        )
    if count > MAX_EVENT_CONTACTS:
        return ContactChoice(
            "stepping", "automatic", f"{count} contacts, more than {MAX_EVENT_CONTACTS}: time-stepping"
        )
    return ContactChoice("event", "automatic", f"{count} contacts, each with modes (at most {MAX_EVENT_CONTACTS})")


def default_contacts(scene: Scene) -> str:
    """The treatment (``held``, ``event`` or ``stepping``) a run of ``scene`` takes unless asked for one."""
    choice = contact_choice(scene)
    return "held" if choice is None else choice.treatment


def resolve_contacts(scene: Scene, contacts: str | None) -> tuple[str | None, ContactChoice | None]:
    """``simulate``'s ``contacts`` (``held``: rows; ``event``; ``stepping``; None or ``auto``: the scene's choice,
    :func:`contact_choice`) as (``event``, ``stepping`` or None for held rows; the choice to report, None for a scene
    without contacts or joint friction).

    Raises:
        PinstabError: another value (naming the valid ones); a treatment other than ``event`` for a scene with joint
            friction (naming the frictions, their joints and the treatment that takes them).
    """
    valid = (*CONTACT_TREATMENTS, "auto")
    if contacts is not None and contacts not in valid:
        raise PinstabError(f"contacts: unknown treatment {contacts!r}; valid: {', '.join(valid)}")
    automatic = contact_choice(scene)
    if contacts is None or contacts == "auto":
        choice = automatic
        treatment = "held" if choice is None else choice.treatment
    else:
        treatment = contacts
        choice = None if automatic is None else ContactChoice(treatment, "asked", f"asked for {treatment}")
    frictions = joint_frictions(scene.forces)
    if frictions and treatment != "event":
        raise refusal(frictions, f"{treatment} contacts (contacts={treatment!r}, --contacts {treatment})")
    return (None if treatment == "held" else treatment), choice


def refuse_held_options(scene: Scene, treatment: str, choice: ContactChoice | None, given: list[str]) -> None:
    """Refuse the options of held rows in ``given`` (a stabilization method, a KKT backend, their options) on a run
    whose contacts are ``treatment`` (``event`` or ``stepping``), which has no use for them.

    Raises:
        PinstabError: some given, naming them, the treatment and how it was chosen, and ``contacts="held"``.
    """
    if not given:
        return
    how = "asked for" if choice is None or choice.chosen == "asked" else choice.why
    raise PinstabError(
        f"{', '.join(given)}: scene {scene.name}'s contacts are {treatment} ({how}), without a stabilization method "
        "or KKT backend; give contacts='held' to hold them as constraint rows with these options"
    )
