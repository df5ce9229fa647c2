"""Exit codes of the command line, and the failure that keeps a run's outputs."""

from __future__ import annotations

from typing import Any

from ..errors import PinstabError

EXIT_OK, EXIT_BAD_INPUT, EXIT_DIVERGED, EXIT_SIGNAL_BASE = 0, 2, 3, 128  # a signal: 128 + its number
EXIT_STOPPED = 4  # the run ended at a contact event asked for with --stop-on
EXIT_CONTACT_FAILED = 5  # contacts or servos with no solution during the run (Contact/ServoInfeasibleError)
EXIT_POINTS_FAILED = 6  # a sweep that ended with points whose runs failed (their rows hold the errors)
EXIT_CODES = (
    f"exit codes: {EXIT_OK} success; {EXIT_BAD_INPUT} bad input (a message, no traceback); {EXIT_DIVERGED} divergence "
    f"(--json: the figures up to the last finite state, --save: the trajectory up to there); {EXIT_STOPPED} stopped at "
    f"the contact event asked for with --stop-on; {EXIT_CONTACT_FAILED} contacts or servos with no solution during the "
    f"run (held contacts that cannot hold, a lost grasp, Painleve's paradox, servos the controls cannot realize); "
    f"with {EXIT_STOPPED} and {EXIT_CONTACT_FAILED} the JSON, --save, --plot and the recording hold the run up to "
    "the stop; "
    f"{EXIT_POINTS_FAILED} a sweep whose table holds failed points (some or all: their rows name the errors); 130 "
    "Ctrl-C, 143 SIGTERM (--save: the trajectory so far)"
)


class Kept(Exception):
    """A run that failed once started (``error``) whose outputs up to the failure were written (``result``)."""

    def __init__(self, error: PinstabError, result: dict[str, Any]) -> None:
        super().__init__(str(error))
        self.error, self.result = error, result
