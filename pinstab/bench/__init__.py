"""Benchmarks: work-precision sweeps with peers, simulate() against a hand-written loop, scaling."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def save_results(path: Path, results: dict[str, Any]) -> None:
    """Write a benchmark's results as indented JSON (creating the folder) and say where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=1))
    print(f"-> {path}")
