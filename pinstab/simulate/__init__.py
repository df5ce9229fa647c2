"""``simulate()``: assemble, then step a scene with a stabilizer, an integrator and a KKT backend (:mod:`.api`),
by the held path (:mod:`.held`), the contact paths (:mod:`.contacts`: event-driven, time-stepping; which one:
:mod:`.choice`) or, for a run that leaves a joint limit, the event path (:mod:`.limits`); what they share is in
:mod:`.loop`."""

from .api import DEFAULT_DT, ERROR_CONTROLLED_INTEGRATOR, FIXED_STEP_INTEGRATOR, default_integrator, simulate
from .choice import MAX_EVENT_CONTACTS, ContactChoice, contact_choice, default_contacts
from .contacts import EVENT_RTOL, HELD_ONLY, event_contacts, stop_kinds
from .integrator_choice import AUTO
from .limits import limit_left
from .loop import DEFAULT_DRIFT_LIMIT, MIN_RTOL, Interrupted, error_control, failure_stop, kept_samples

__all__ = [
    "AUTO",
    "DEFAULT_DRIFT_LIMIT",
    "DEFAULT_DT",
    "ERROR_CONTROLLED_INTEGRATOR",
    "EVENT_RTOL",
    "FIXED_STEP_INTEGRATOR",
    "HELD_ONLY",
    "MAX_EVENT_CONTACTS",
    "MIN_RTOL",
    "ContactChoice",
    "Interrupted",
    "contact_choice",
    "default_contacts",
    "default_integrator",
    "error_control",
    "event_contacts",
    "failure_stop",
    "kept_samples",
    "limit_left",
    "simulate",
    "stop_kinds",
]
