"""What the commands print: one JSON object, or lines a person reads; a closed stdout ends quietly."""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

EVENT_ROWS = 20  # contact events listed in text output (all of them in the JSON)


def stopped_text(stopped: dict[str, Any]) -> str:
    """``info.stopped`` in words: what, when [s], which contact and how its mode changed."""
    event = stopped.get("event")
    if event is None:
        return f"{stopped['reason']} at t = {stopped['t']:.9g} s ({stopped['error']})"
    change = f"{event['from']} -> {event['to']} ({event['cause']})"
    return f"{stopped['reason']} at t = {stopped['t']:.9g} s: contact {event['contact']} {change}"


def write(text: str) -> None:
    """Print ``text`` on stdout; a reader that closed it (``| head``) ends the output quietly: stdout is
    pointed at /dev/null so that the interpreter's last flush does not fail again."""
    try:
        print(text, flush=True)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
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
    slip speed [m/s]), and how many more there are; no lines without events."""
    if not events:
        return []
    lines = [
        f"contact events ({len(events)}):",
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
    """JSON-safe: numpy scalars to Python, non-finite floats to None."""
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value
