"""Screenshots of a recording in headless Chromium (Debian package ``chromium``), offline."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
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


def chromium() -> str | None:
    """Path of a Chromium executable, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def screenshot(
    html: str | Path, png: str | Path, time_s: float, size: tuple[int, int] = (800, 600), budget_ms: int = 8000
) -> Path:
    """Open a recording paused at ``time_s`` [s] and save what the browser shows as a PNG.

    Raises:
        PinstabError: no Chromium, or it failed (its last output lines are in the message).
    """
    executable = chromium()
    if executable is None:
        raise PinstabError("headless screenshots need Chromium: apt-get install chromium")
    html, png = Path(html).resolve(), Path(png).resolve()
    with tempfile.TemporaryDirectory() as profile:
        command = [
            executable,
            *CHROMIUM_FLAGS,
            f"--user-data-dir={profile}",
            f"--window-size={size[0]},{size[1]}",
            f"--virtual-time-budget={budget_ms}",
            f"--screenshot={png}",
            f"{html.as_uri()}#t={time_s}",
        ]
        completed = subprocess.run(command, capture_output=True, text=True, timeout=180)
    if completed.returncode != 0 or not png.is_file():
        tail = "\n".join((completed.stderr or completed.stdout).strip().splitlines()[-3:])
        raise PinstabError(f"Chromium could not screenshot {html.name} (exit {completed.returncode}): {tail}")
    return png
