"""The ``pinstab`` command line: ``check`` a scene, ``run`` a simulation, analyse a ``grasp``, map
``stability``, ...: one module per command in :mod:`pinstab.cli.commands`.

Exit codes (:data:`~pinstab.cli.exits.EXIT_CODES`): 0 success, 2 bad input (message, no traceback), 3 divergence
(any blow-up, whatever the solver; with ``--json`` the figures up to the last finite state; ``--save`` writes the
partial trajectory), 4 stopped at a contact event asked for with ``--stop-on``, 5 contacts with no solution during
the run (held contacts that cannot hold, a lost grasp, Painleve's paradox), 130 Ctrl-C and 143 SIGTERM (one line;
``--save`` writes the partial trajectory). With 4 and 5 the run's JSON, ``--save`` file, ``--plot`` chart and
recording are written up to the stop. A closed stdout (``| head``) ends quietly.
"""

from .commands import COMMANDS, SIMULATING
from .dispatch import build_parser, main
from .exits import EXIT_BAD_INPUT, EXIT_CONTACT_FAILED, EXIT_DIVERGED, EXIT_OK, EXIT_STOPPED
from .output import EVENT_ROWS, events_table, stopped_text

__all__ = [
    "COMMANDS",
    "EVENT_ROWS",
    "EXIT_BAD_INPUT",
    "EXIT_CONTACT_FAILED",
    "EXIT_DIVERGED",
    "EXIT_OK",
    "EXIT_STOPPED",
    "SIMULATING",
    "build_parser",
    "events_table",
    "main",
    "stopped_text",
]
