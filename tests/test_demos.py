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


def test_stability_map_demo_writes_a_map(tmp_path):
    out = run_demo("stability_map.py", "--grid", "5", "-o", str(tmp_path / "map.png"))
    agreement = float(re.search(r"agree on ([0-9.]+) % of 25 cells", out).group(1))
    assert agreement >= 80.0
    assert (tmp_path / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_allegro_lift_demo_writes_a_recording_and_a_chart(tmp_path):
    """A short stretch of the lift (0.4 s: the path starts at 0.25 s) tracks to 1e-9 m inside the cones and
    writes both files; without the internal-force QP the grasp is lost at once, naming every contact that
    leaves its cone (all four, worst first)."""
    html, png = tmp_path / "lift.html", tmp_path / "lift.png"
    out = run_demo("allegro_lift.py", "--duration", "0.4", "-o", str(html), "--chart", str(png))
    assert float(re.search(r"max position error: ([0-9.e+-]+) m", out).group(1)) < 1e-9
    assert float(re.search(r"min cone margin: ([0-9.e+-]+) N", out).group(1)) > 0
    assert html.stat().st_size > 100_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    out = run_demo("allegro_lift.py", "--no-internal-forces", "-o", str(html), "--chart", str(png))
    assert "without internal forces: grasp lost at t = 0 s: 4 contacts leave their cones: contact 'ring'" in out
    assert all(f"contact '{name}'" in out for name in ("index", "middle", "ring", "thumb"))
