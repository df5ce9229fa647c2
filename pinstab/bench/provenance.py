"""What produced a benchmark's results: the pinstab commit, the versions it ran with, the machine and the command."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

# The distributions whose releases change a benchmark's figures: pinstab's own dependencies and the peers.
VERSIONED = ("pin", "numpy", "scipy", "proxsuite", "mujoco", "meshcat", "example-robot-data", "dask")


def _git(*args: str) -> str | None:
    """The output of a git command run in the source checkout, or None where there is no checkout or no git."""
    root = Path(__file__).resolve().parents[2]
    try:
        done = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=10, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip()


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


# What a benchmark's figures depend on: the source, not the results that benchmarks write (a run of several
# benchmarks in one checkout changes those as it goes).
SOURCE = ("pinstab", "cpp", "benchmarks/*.py", "CMakeLists.txt", "pyproject.toml")


def provenance() -> dict[str, Any]:
    """The commit (``dirty`` when the source differs from it: uncommitted changes to tracked files of
    :data:`SOURCE`), the versions of pinstab's dependencies and peers, Python, the machine (CPU count) and the
    command line of this process."""
    status = _git("status", "--porcelain", "--untracked-files=no", "--", *SOURCE)
    return {
        "commit": _git("rev-parse", "HEAD"),
        "dirty": None if status is None else bool(status),
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "python": platform.python_version(),
        "machine": f"{platform.machine()}, {os.cpu_count()} CPUs",
        "versions": {name: _version(name) for name in VERSIONED if _version(name) is not None},
    }
