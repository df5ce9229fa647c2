"""A joint limit passed and left again within one error-controlled step (issue 34, the fuzzer's
test_joint_started_on_its_limit_stays_within): the event loop checked the limits' gaps at the ends of its steps only,
so that a joint that went beyond its bound and came back inside within a step was never stopped (a start on the bound
moving into it, one step of 0.02 s: 7.6e-4 rad past it; a second link thrown toward its bound by the first one's
impact: 8.3e-4 rad). The gaps are now checked on each step's dense output (pinstab/integration/events.py).

The link: 1 kg, centre of mass 0.15 m from the joint, I = 0.0075 + 0.15^2 = 0.03 kg m^2 about the joint, gravity
along -y: at angle q its angular acceleration is -alpha cos q, alpha = m g l / I = 49.05 rad/s^2.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from pinstab.simulate import simulate

sys.path.insert(0, str(Path(__file__).parent))
from fuzzing import time_limit, toml_document  # noqa: E402
from test_fuzz_tables import limited_chain_urdf  # noqa: E402

INERTIA = 0.0075 + 1.0 * 0.15**2  # [kg m^2] about the joint
ALPHA = 1.0 * 9.81 * 0.15 / INERTIA  # [rad/s^2] gravity's angular acceleration at q = 0
SLACK = 1e-9  # [rad] beyond a bound: the located event's 1e-12 rad and the dense output's rounding, with margin


def _run(tmp_path: Path, limits: list, start: list, speed: list, duration: float):
    names = [f"j{k}" for k in range(len(limits))]
    scene = {
        "gravity": [0.0, -9.81, 0.0],
        "robot": {"urdf_text": limited_chain_urdf(limits)},
        "initial": {"q": dict(zip(names, start, strict=True)), "v": dict(zip(names, speed, strict=True))},
    }
    path = tmp_path / "chain.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    with time_limit(10):
        return simulate(str(path), dt=1e-3, duration=duration)


def _impacts(run, limit: str) -> list[float]:
    return [e["t"] for e in run.info.contact_events if e["contact"] == limit and e["to"] == "closing"]


def test_start_on_the_bound_is_stopped_at_once(tmp_path: Path) -> None:
    """The fuzzer's one-link case: on its upper bound 0.99994 rad at 0.2 rad/s into it, gravity turning it back
    within the event loop's first step; now an impact at once (e = 0), then q = upper - alpha cos(upper) t^2 / 2."""
    upper = 0.9999358242495255
    run = _run(tmp_path, [(0.0, upper)], [upper], [0.20040341384365146], 0.1)
    assert run.q[:, 0].max() <= upper + SLACK
    assert len(_impacts(run, "j0 upper")) == 1 and _impacts(run, "j0 upper")[0] < 1e-10
    t = run.t[1:11]  # to 10 ms
    expected = upper - ALPHA * math.cos(upper) * t**2 / 2  # cos q varies by 1e-3 relative over the 1.3e-3 rad fallen
    assert np.max(np.abs(run.q[1:11, 0] - expected)) <= 5e-6


def test_bound_reached_and_left_within_a_step_is_an_impact(tmp_path: Path) -> None:
    """From 2e-5 rad inside its upper bound 1 rad at 0.05 rad/s toward it, gravity turning it back: it would pass
    the bound by v^2 / (2 a) - 2e-5 = 2.7e-5 rad for 1.4 ms, inside one of the loop's steps. It hits the bound at
    t = (v - sqrt(v^2 - 2 a gap)) / a, a = alpha cos 1 (the gap's closed form; cos varies by 2e-5 relative)."""
    upper, gap, speed = 1.0, 2e-5, 0.05
    run = _run(tmp_path, [(0.0, upper)], [upper - gap], [speed], 0.01)
    a = ALPHA * math.cos(upper)
    assert speed**2 / (2 * a) > gap  # without the bound it would pass it
    hits = _impacts(run, "j0 upper")
    assert len(hits) == 1
    assert hits[0] == pytest.approx((speed - math.sqrt(speed**2 - 2 * a * gap)) / a, rel=1e-4)
    assert run.q[:, 0].max() <= upper + SLACK


def test_second_link_thrown_toward_its_bound_is_stopped(tmp_path: Path) -> None:
    """The fuzzer's two-link case: the first joint on its upper bound at 5 rad/s into it, the second at 5 rad/s;
    the first one's impact throws the second past its upper bound -1.37740 rad (8.3e-4 rad) within a step."""
    limits = [(-1.7043847157419592, 1.2956152842580408), (-1.8568180456363867, -1.3773998258677516)]
    run = _run(tmp_path, limits, [1.2956152842580408, -1.6171089357520692], [5.0, 5.0], 0.1)
    for k, (lower, upper) in enumerate(limits):
        assert run.q[:, k].min() >= lower - SLACK and run.q[:, k].max() <= upper + SLACK, k
    assert _impacts(run, "j0 upper")[0] < 1e-10 and _impacts(run, "j1 upper")
