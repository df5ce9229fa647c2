"""Benchmarks: work-precision sweeps with peers, simulate() against a hand-written loop, scaling."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pinstab.bench.provenance import provenance


def stamped(results: dict[str, Any]) -> dict[str, Any]:
    """``results`` with a ``provenance`` entry first: the commit, versions and command that produced them."""
    return {"provenance": provenance(), **results}


def save_results(path: Path, results: dict[str, Any]) -> None:
    """Write a benchmark's results, stamped with their provenance, as indented JSON (creating the folder) and say
    where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(stamped(results), indent=1) + "\n")
    print(f"-> {path}")
