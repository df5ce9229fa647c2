"""Force elements, one kind per module, each registered in :data:`FORCE_KINDS` (the grasp controllers
``grasp-hold`` and ``grasp-control`` live in :mod:`pinstab.grasp`, which registers them on import)."""

from ..registry import load_extensions
from .base import FORCE_KINDS, ForceElement
from .external_force import ExternalForce
from .joint_torque import JointTorque
from .spring_damper import SpringDamper

load_extensions(__name__, __path__)

__all__ = ["FORCE_KINDS", "ExternalForce", "ForceElement", "JointTorque", "SpringDamper"]
