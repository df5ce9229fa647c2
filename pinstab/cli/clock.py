"""The wall time a command's user waits, counted from the start of the process (the interpreter's start-up and the
imports included), and its split into start-up, set-up, stepping, post-processing and output."""

from __future__ import annotations

import os
import time
from typing import Any

IMPORTED = time.perf_counter()  # the fallback origin: where /proc is missing, the first import of this module


def process_started() -> float:
    """The ``time.perf_counter()`` reading [s] at which this process started: from its start time in
    ``/proc/self/stat`` (Linux; to the kernel's clock tick, 10 ms), else when this module was first imported."""
    try:
        with open("/proc/self/stat", encoding="ascii") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()  # after the command name, which may hold spaces
        started = int(fields[19]) / os.sysconf("SC_CLK_TCK")  # field 22: clock ticks after boot
        since = time.clock_gettime(time.CLOCK_BOOTTIME) - started
    except (OSError, IndexError, ValueError, AttributeError):  # no /proc, no CLOCK_BOOTTIME (macOS, Windows)
        return IMPORTED
    return time.perf_counter() - max(since, 0.0)


def command_timings(run: dict[str, float], began: float, simulated: float, writing: float) -> dict[str, Any]:
    """``wall_s``, the time since the process started [s], and ``timings``, its split [s]: ``startup_s`` (the
    interpreter, the imports, the arguments: until ``began``), ``setup_s`` (the scene loaded and the run's set-up),
    ``stepping_s``, ``post_s`` (the run's post-processing, the summary figures, a reference's error; until
    ``writing``) and ``output_s`` (the files written: ``--save``, ``--plot``); ``run`` is the simulate() call's own
    split (``info.timings``), ``began``, ``simulated`` and ``writing`` ``time.perf_counter()`` readings."""
    now = time.perf_counter()
    origin = min(process_started(), began)
    stepping, post = run.get("stepping_s", 0.0), run.get("post_s", 0.0)
    timings = {
        "startup_s": began - origin,
        "setup_s": simulated - began - stepping - post,
        "stepping_s": stepping,
        "post_s": post + writing - simulated,
        "output_s": now - writing,
    }
    return {"wall_s": now - origin, "timings": timings}
