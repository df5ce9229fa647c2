"""A command of the command line: its arguments, what it does, how its result reads as text."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ...errors import PinstabError


@dataclass(frozen=True)
class Command:
    """One ``pinstab`` sub-command.

    Attributes:
        name: what the user types (``run``). help: one line for ``pinstab --help``.
        arguments: adds the command's arguments to its parser. execute: does the work from the parsed
            arguments and returns the result (printed as JSON with ``--json``).
        text: the result as lines a person reads (default: one ``key  value`` line per figure).
        simulates: the command runs a simulation (it may stop at a contact event: exit 4).
        failures: what failed in a finished result, in words (a sweep's failed points), or None: the command
            then exits 6 with it on stderr.
        order: place in ``pinstab --help``.
    """

    name: str
    help: str
    arguments: Callable[[argparse.ArgumentParser], None]
    execute: Callable[[argparse.Namespace], dict[str, Any]]
    text: Callable[[dict[str, Any]], str] | None = None
    simulates: bool = False
    failures: Callable[[dict[str, Any]], str | None] | None = None
    order: int = 100


COMMANDS: dict[str, Command] = {}


def register(command: Command) -> Command:
    """Add a command (each module of :mod:`pinstab.cli.commands` registers its own)."""
    if command.name in COMMANDS:
        raise PinstabError(f"command {command.name!r} is already registered")
    COMMANDS[command.name] = command
    return command
