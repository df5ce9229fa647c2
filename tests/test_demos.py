"""The demos run headless and print the figures they promise."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

DEMOS = Path(__file__).resolve().parents[1] / "demos"


def run_demo(*argv: str) -> str:
    completed = subprocess.run(
        [sys.executable, str(DEMOS / argv[0]), *argv[1:]], capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 0, completed.stderr
    return completed.stdout


def test_compare_methods_lists_every_method():
    out = run_demo("compare_methods.py", "--duration", "0.2")
    for method in ("none", "baumgarte", "projection", "post", "pinocchio"):
        assert re.search(rf"^{method}\s+\d\.\d\de-\d\d", out, re.MULTILINE), out


def test_user_constraint_matches_closed_form():
    out = run_demo("user_constraint.py")
    error = float(re.search(r"closed form\| over 2 s: ([0-9.e+-]+) N", out).group(1))
    assert error < 1e-6
