"""The commands of ``pinstab``, one module each, registered in :data:`COMMANDS` when imported: a new command is
one new module here."""

from ...registry import load_extensions
from .base import COMMANDS, Command, register

load_extensions(__name__, __path__)

SIMULATING = tuple(name for name, command in COMMANDS.items() if command.simulates)

__all__ = ["COMMANDS", "SIMULATING", "Command", "register"]
