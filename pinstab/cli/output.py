"""What the commands print: one JSON object, or lines a person reads; a closed stdout ends quietly; with ``--json``
nothing but the JSON on stdout (:func:`json_only_stdout`)."""

from __future__ import annotations

import ctypes
import json
import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

import numpy as np

EVENT_ROWS = 20  # contact events listed in text output (all of them in the JSON)
_held: list[TextIO] = []  # the original stdout, while json_only_stdout() points file descriptor 1 at stderr


@contextmanager
def json_only_stdout() -> Iterator[None]:
    """Stdout for the JSON alone: while the command works, file descriptor 1 points at stderr, so that whatever writes
    to it below the JSON (LAPACK's ``DLASCL`` complaints from Fortran and C, a library's print) lands on stderr, and
    :func:`write` prints to the original stdout, held meanwhile (or to ``sys.stdout`` when it is not descriptor 1: a
    capture). Descriptor 1 is restored on every way out (a result, an error, Ctrl-C), after what Python and C buffered
    for it went to stderr (POSIX: C's buffers flushed by ``fflush(NULL)``)."""
    stdout = sys.stdout
    if stdout is None:  # descriptor 1 closed from the start: no stdout to keep (print writes nothing), as without
        yield
        return
    stdout.flush()
    saved = os.dup(1)
    held = stdout
    try:
        if _descriptor(stdout) == 1:
            held = open(saved, "w", encoding=stdout.encoding, errors=stdout.errors, closefd=False)
        _held.append(held)
        os.dup2(2, 1)
        yield
    finally:
        try:
            if held in _held:
                _held.remove(held)
            if held is not stdout:
                held.close()
            sys.stdout.flush()  # Python's and C's buffered text for descriptor 1 to stderr, before it is stdout again
            ctypes.CDLL(None).fflush(None)
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def _descriptor(stream: TextIO) -> int | None:
    """The file descriptor a stream writes to, or None (an in-memory stream, a capture)."""
    try:
        return stream.fileno()
    except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation is an OSError and a ValueError
        return None


def stopped_text(stopped: dict[str, Any]) -> str:
    """``info.stopped`` in words: what, when [s], which contact and how its mode changed, or the error's class; the
    fields it lacks left out (a file may hold an older one: ``{"reason": "stream cut off", "t": ...}`` before
    ``info.cut_short``)."""
    t = stopped.get("t")
    text = str(stopped.get("reason", "stopped"))
    text += f" at t = {t:.9g} s" if isinstance(t, int | float) else ""
    event = stopped.get("event")
    if isinstance(event, dict):
        change = f"{event.get('from')} -> {event.get('to')} ({event.get('cause')})"
        return f"{text}: contact {event.get('contact')} {change}"
    return text if stopped.get("error") is None else f"{text} ({stopped['error']})"


def write(text: str) -> None:
    """Print ``text`` on stdout (the original one, held by :func:`json_only_stdout`); a reader that closed it
    (``| head``) ends the output quietly: stdout is pointed at /dev/null so that the interpreter's last flush does not
    fail again."""
    stream = _held[-1] if _held else sys.stdout
    try:
        print(text, file=stream, flush=True)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, stream.fileno())
        os.close(devnull)


def emit(result: dict[str, Any], as_json: bool, text: Callable[[dict[str, Any]], str] | None = None) -> None:
    """Print a command's result: JSON, the command's own text format, or one ``key  value`` line per figure
    and the contact events' table."""
    if as_json:
        write(json.dumps(clean(result)))
        return
    if text is not None:
        write(text(result))
        return
    shown = {key: value for key, value in result.items() if key != "contact_events"}
    if shown.get("stopped"):
        shown["stopped"] = stopped_text(shown["stopped"])
    width = max(len(k) for k in shown)
    lines = [f"{key:<{width}}  {f'{value:.6g}' if isinstance(value, float) else value}" for key, value in shown.items()]
    write("\n".join(lines + events_table(result.get("contact_events") or [])))


def events_table(events: list[dict[str, Any]], rows: int = EVENT_ROWS) -> list[str]:
    """The first ``rows`` contact events as text lines (time [s], contact, from -> to, cause, normal force [N],
    slip speed [m/s; rad/s for a contact's torsion or rolling]), and how many more there are; no lines without
    events."""
    if not events:
        return []
    lines = [
        f"contact events ({len(events)}; slip in rad/s for torsion and rolling):",
        f"  {'t [s]':>14}  {'contact':<12} {'from -> to':<24} {'f_n [N]':>10}  {'slip [m/s]':>10}  cause",
    ]
    for event in events[:rows]:
        change = f"{event['from']} -> {event['to']}"
        lines.append(
            f"  {event['t']:>14.9g}  {event['contact']:<12} {change:<24} {event['force'][0]:>10.4g}  "
            f"{float(np.hypot(*event['slip_velocity'])):>10.3g}  {event['cause']}"
        )
    if len(events) > rows:
        lines.append(f"  ... and {len(events) - rows} more (all of them in --json)")
    return lines


def clean(value: Any) -> Any:
    """JSON-safe: numpy arrays and scalars to Python, paths to strings, non-finite floats to None."""
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return clean(value.tolist())
    if isinstance(value, (np.floating, float)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.generic):  # integers, booleans
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value
