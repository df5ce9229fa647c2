"""Contacts: their modes (sticking, sliding, separated) and the events between them."""

from .modes import ContactEvent, Mode

__all__ = ["ContactEvent", "Mode"]
