"""A start on a joint limit moving into it (issue 34, the fuzzer's test_start_on_a_limit_moving_into_it_runs): an
impact at once (restitution 0: the joint stops), then released where it stopped, a rounding beyond its bound, and the
run goes on (pinstab/integration/events.py); it never left t = 0 (the limit reached again at once, over and over).
A start moving into its limit slower than alpha dt / 2 (the joint back inside by the first sample) went the held path,
which missed the impact (pinstab/simulate/limits.py: such a start counts as leaving the limit at t = 0).

The link: 1 kg, centre of mass 0.15 m from the joint, I = 0.0075 + 0.15^2 = 0.03 kg m^2 about the joint, limits
[-3, 0] rad, gravity pulling it away from its upper bound: after the impact q(t) = -alpha t^2 / 2 with alpha =
m g l / I = 49.05 rad/s^2 (cos q > 1 - 3e-6 for t <= 10 ms).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from pinstab.simulate import simulate

sys.path.insert(0, str(Path(__file__).parent))
from fuzzing import time_limit, toml_document  # noqa: E402
from test_fuzz_tables import LIMIT_HANG  # noqa: E402

INERTIA = 0.0075 + 1.0 * 0.15**2  # [kg m^2] about the joint
ALPHA = 1.0 * 9.81 * 0.15 / INERTIA  # [rad/s^2] gravity's angular acceleration at q = 0


@pytest.mark.parametrize("speed", [0.6, 1e-3])
def test_start_on_a_limit_moving_into_it_is_an_impact(speed: float, tmp_path: Path) -> None:
    scene = dict(LIMIT_HANG, initial={"q": {"j0": 0.0}, "v": {"j0": speed}})
    path = tmp_path / "limit.toml"
    path.write_text(toml_document(scene), encoding="utf-8")
    with time_limit(10):
        run = simulate(str(path), dt=1e-3, duration=0.01)
    impacts = [event for event in run.info.contact_events if event["cause"] == "impact"]
    assert [(event["contact"], event["to"]) for event in impacts] == [
        ("j0 upper", "closing"),
        ("j0 upper", "separated"),
    ]
    t_impact = impacts[0]["t"]
    assert 0.0 < t_impact <= 2e-12 / speed  # at once: the start's speed covers the limit's 1e-12 rad of slack
    before = speed - ALPHA * t_impact  # [rad/s] the speed at the impact
    assert abs(impacts[0]["impulse"][0] - INERTIA * before) <= 1e-9 * INERTIA * speed  # e = 0: all of I v taken
    t = run.t[1:]
    assert np.allclose(run.v[1:, 0], -ALPHA * t, rtol=1e-5, atol=0.0)  # the velocity after: -e times before, e = 0
    assert np.allclose(run.q[1:, 0], -ALPHA * t**2 / 2, rtol=1e-5, atol=1e-11)
    assert run.q[:, 0].max() <= 1e-11  # within the bound but for the located slack
