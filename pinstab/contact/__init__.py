"""Contacts: the scene's rigid objects, friction cones, contact models (what a contact transmits and can
carry), and contact modes (sticking, sliding, separated) with the events between them. The constraints
and the scene use them: they sit below them."""

from .cones import FrictionCone
from .models import WRENCH_BASES, ContactLimits
from .modes import ContactEvent, Mode
from .objects import SceneObject

__all__ = ["WRENCH_BASES", "ContactEvent", "ContactLimits", "FrictionCone", "Mode", "SceneObject"]
