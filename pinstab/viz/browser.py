"""Recordings opened in headless Chromium (Debian package ``chromium``), offline: screenshots, and the
page's title and console messages (the browser test's check that every command ran without errors)."""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..errors import PinstabError

CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    # WebGL through the software rasterizer; every host name fails to resolve, so the page is offline
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--host-resolver-rules=MAP * ~NOTFOUND",
)
# a console line in Chromium's log: [pid:tid:date:LEVEL:CONSOLE:line] "message", source: url (line)
CONSOLE_LINE = re.compile(r':CONSOLE[:(]?\d*\)?\] "(.*)", source: ')
# the software rasterizer's own performance notes, not the page's
DRIVER_NOTE = "GL Driver Message"


@dataclass
class PageLoad:
    """An opened recording: its title (``pinstab ready: NAME`` once every command ran) and the messages
    the page wrote to the console (errors, warnings, logs; the WebGL driver's notes left out)."""

    title: str
    console: list[str]


def chromium() -> str | None:
    """Path of a Chromium executable, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def _run(html: Path, time_s: float, options: list[str], budget_ms: int) -> subprocess.CompletedProcess:
    """Open ``html`` paused at ``time_s`` [s] with extra Chromium ``options``, in a fresh profile."""
    executable = chromium()
    if executable is None:
        raise PinstabError("headless Chromium is needed: apt-get install chromium")
    with tempfile.TemporaryDirectory() as profile:
        command = [
            executable,
            *CHROMIUM_FLAGS,
            f"--user-data-dir={profile}",
            f"--virtual-time-budget={budget_ms}",
            *options,
            f"{html.as_uri()}#t={time_s}",
        ]
        return subprocess.run(command, capture_output=True, text=True, timeout=180)


def _failure(html: Path, completed: subprocess.CompletedProcess, what: str) -> PinstabError:
    tail = "\n".join((completed.stderr or completed.stdout).strip().splitlines()[-3:])
    return PinstabError(f"Chromium could not {what} {html.name} (exit {completed.returncode}): {tail}")


def screenshot(
    html: str | Path, png: str | Path, time_s: float, size: tuple[int, int] = (800, 600), budget_ms: int = 8000
) -> Path:
    """Open a recording paused at ``time_s`` [s] and save what the browser shows, ``size`` [px], as a PNG.

    Raises:
        PinstabError: no Chromium, or it failed (its last output lines are in the message).
    """
    html, png = Path(html).resolve(), Path(png).resolve()
    completed = _run(html, time_s, [f"--window-size={size[0]},{size[1]}", f"--screenshot={png}"], budget_ms)
    if completed.returncode != 0 or not png.is_file():
        raise _failure(html, completed, "screenshot")
    return png


def open_page(html: str | Path, time_s: float, budget_ms: int = 8000) -> PageLoad:
    """Open a recording paused at ``time_s`` [s]; its title and console messages once it has run.

    Raises:
        PinstabError: no Chromium, or it failed (its last output lines are in the message).
    """
    html = Path(html).resolve()
    completed = _run(html, time_s, ["--dump-dom", "--enable-logging=stderr", "--v=0"], budget_ms)
    title = re.search(r"<title>(.*?)</title>", completed.stdout, re.DOTALL)
    if completed.returncode != 0 or title is None:
        raise _failure(html, completed, "open")
    messages = [match.group(1) for match in map(CONSOLE_LINE.search, completed.stderr.splitlines()) if match]
    return PageLoad(title.group(1), [message for message in messages if DRIVER_NOTE not in message])
