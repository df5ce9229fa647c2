"""The time grid (the last step lands on the duration) and the typed run information (RunInfo with
solver statistics) through JSON and NPZ."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pinstab import PinstabError, RunInfo, Trajectory, simulate
from pinstab.cli import main
from pinstab.integration import TimeGrid


@pytest.mark.parametrize(
    ("dt", "duration", "steps", "last"),
    [(1e-3, 1.0, 1000, 1e-3), (7e-4, 1.0, 1429, 1.0 - 1428 * 7e-4), (0.1, 0.3, 3, 0.1), (0.5, 0.2, 1, 0.2)],
)
def test_time_grid_ends_on_the_duration(dt, duration, steps, last):
    grid = TimeGrid.of(dt, duration)
    assert grid.steps == steps
    assert grid.time(steps) == duration
    assert grid.time(steps) - grid.time(steps - 1) == pytest.approx(last, rel=1e-9)
    assert all(grid.time(k) < grid.time(k + 1) for k in range(steps))


def test_cli_reports_the_end_time(capsys):
    """The issue's line: ``--dt 7e-4 --duration 1`` runs 1429 steps, the last one shortened, to 1.0 s."""
    assert main(["run", "fourbar", "--dt", "7e-4", "--duration", "1", "--json", "--quiet"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["t_end"] == pytest.approx(1.0, abs=1e-15) and result["steps"] == 1429
    assert result["duration"] == 1.0 and result["dt"] == 7e-4


def test_shortened_last_step_keeps_the_accuracy():
    """A grid of 7e-4 s ending with a 4e-4 s step against one of 5e-4 s (dividing 1 s): RK4 + projection
    agree at the common end time to the accuracy of the method (~dt^4), not to one step's motion."""
    uneven = simulate("fourbar", method="projection", dt=7e-4, duration=1.0)
    even = simulate("fourbar", method="projection", dt=5e-4, duration=1.0)
    assert uneven.t[-1] == even.t[-1] == 1.0
    assert np.abs(uneven.q[-1] - even.q[-1]).max() < 1e-8
    assert np.abs(uneven.q[-1] - uneven.q[-2]).max() > 1e-4  # one step's motion is much larger


def test_bad_grid_is_refused():
    with pytest.raises(PinstabError, match="exceed the 20,000,000"):
        simulate("fourbar", dt=1e-9, duration=1.0)
    with pytest.raises(PinstabError, match="dt must be a positive number, got True"):
        simulate("fourbar", dt=True)


def test_run_info_round_trips_through_npz_and_json(tmp_path):
    # ProxQP itself (direct off: fivebar's zero out-of-plane row left out, its Cholesky solve would take every step)
    traj = simulate(
        "fivebar", method="baumgarte", dt=2e-3, duration=0.1, solver="proxsuite", solver_options={"direct": False}
    )
    info = traj.info
    statistics = info.solver_statistics
    assert statistics.solves == 4 * traj.steps  # RK4: four evaluations a step
    assert sum(statistics.status_counts.values()) == statistics.solves
    assert set(statistics.status_counts) <= {"PROXQP_SOLVED", "PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE"}
    assert 0 < statistics.worst_primal_residual < 1e-8 and statistics.worst_dual_residual < 1e-8
    assert info.assembly is not None and info.assembly.residual < 1e-12
    assert info.row_kinds == {"end-effector": "equality"} and info.t_end == 0.1
    back = Trajectory.load(traj.save(tmp_path / "run.npz"))
    assert back.info == info
    assert RunInfo.from_dict(json.loads(json.dumps(info.to_dict()))) == info
    with pytest.raises(PinstabError, match="unknown field 'colour'"):
        RunInfo.from_dict({**info.to_dict(), "colour": "red"})
