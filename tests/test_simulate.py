"""simulate(): divergence handling, trajectory files, drift growth without stabilization."""

from __future__ import annotations

import numpy as np
import pytest

from pinstab import DivergenceError, PinstabError, Trajectory, simulate
from pinstab.errors import UnstableGainsWarning


def test_divergence_stops_with_the_last_finite_state():
    # explicit Euler with Kd dt = 20 is far outside its stability region (|1 - Kd dt| > 1)
    with pytest.raises(DivergenceError) as info, pytest.warns(UnstableGainsWarning):
        simulate("fourbar", method="baumgarte", kp=1e6, kd=2e3, integrator="euler", dt=1e-2, duration=5.0)
    error = info.value
    assert np.all(np.isfinite(error.q)) and np.all(np.isfinite(error.v))
    assert 0.0 <= error.time < 5.0
    partial = error.trajectory
    assert partial.t[-1] == pytest.approx(error.time + 1e-2)
    # stopped at the first sample past the limit: position residual, or velocity residual x dt
    last = max(partial.position_drift[-1], partial.velocity_drift[-1] * 1e-2)
    before = max(partial.position_drift[-2], partial.velocity_drift[-2] * 1e-2)
    assert before <= 1.0 and (last > 1.0 or not np.isfinite(last))


def test_drift_grows_without_stabilization_and_not_with_it():
    """Semi-implicit Euler: unstabilized drift keeps growing; Baumgarte's settles at O(1/Kp)."""
    none = simulate("fourbar", method="none", integrator="semi-implicit-euler", dt=1e-3, duration=2.0)
    baumgarte = simulate("fourbar", method="baumgarte", integrator="semi-implicit-euler", dt=1e-3, duration=2.0)
    half = len(none.t) // 4
    assert none.position_drift[-1] > 3 * none.position_drift[:half].max()
    assert baumgarte.position_drift[half:].max() < 1.5 * baumgarte.position_drift[:half].max()
    assert none.position_drift.max() > 20 * baumgarte.position_drift.max()


def test_trajectory_round_trip(tmp_path):
    traj = simulate("fivebar", method="post", dt=2e-3, duration=0.1)
    path = traj.save(tmp_path / "run.npz")
    back = Trajectory.load(path)
    np.testing.assert_array_equal(back.q, traj.q)
    np.testing.assert_array_equal(back.multipliers, traj.multipliers)
    assert back.info.constraint_rows == {"end-effector": [0, 3]}
    assert back.multipliers_of("end-effector").shape == (traj.steps + 1, 3)
    assert list(tmp_path.iterdir()) == [path]


def test_trajectory_save_refuses_bad_paths(tmp_path):
    traj = simulate("fourbar", dt=1e-3, duration=0.01)
    with pytest.raises(PinstabError, match="folder .* does not exist"):
        traj.save(tmp_path / "missing" / "run.npz")
    with pytest.raises(PinstabError, match="must be a .npz file"):
        traj.save(tmp_path / "run.csv")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("name", "value"), [("dt", 0.0), ("duration", -1.0), ("dt", float("nan"))])
def test_bad_step_arguments(name, value):
    with pytest.raises(PinstabError, match=f"{name} must be a positive number"):
        simulate("fourbar", **{name: value})


@pytest.mark.parametrize("method", ["none", "baumgarte", "projection", "post", "pinocchio"])
def test_every_method_runs_the_delta(method):
    """The spatial delta (weld closures) with each method: drift stays small over 0.5 s."""
    traj = simulate("delta", method=method, dt=1e-3, duration=0.5)
    # unstabilized rk4 drift here is truncation error (1.1e-6, falling 16x per halving of dt)
    assert traj.position_drift.max() < (1e-5 if method == "none" else 1e-6)
    assert np.all(np.isfinite(traj.multipliers))


def test_projection_reports_its_iterations():
    """From an inconsistent start (no assembly) the first projection needs several Gauss-Newton steps,
    later ones one or two; every projected state meets the 1e-13 tolerance."""
    traj = simulate("fourbar", method="projection", dt=1e-3, duration=0.05, assemble_initial=False)
    summary = traj.summary()
    assert traj.correction_iterations[1] >= 3
    assert 1 <= traj.correction_iterations[2:].max() <= 2
    assert summary["correction_iterations_max"] == traj.correction_iterations[1]
    assert traj.position_drift[1:].max() <= 1e-13
    assert summary["assembly_iterations"] is None


@pytest.mark.parametrize("contacts", ["held", "event", "stepping"])
def test_a_start_of_the_wrong_length_is_named_on_every_path(contacts):
    """q0 / v0 of the wrong length: a PinstabError naming the lengths, on the held and both contact paths (the
    contact paths used to end in Pinocchio's raw ValueError)."""
    with pytest.raises(PinstabError, match="q0 must have 7 entries and v0 6"):
        simulate("bouncing-ball", contacts=contacts, q0=np.zeros(3), duration=0.01)
    with pytest.raises(PinstabError, match="q0 must have 7 entries and v0 6"):
        simulate("bouncing-ball", contacts=contacts, v0=np.zeros(2), duration=0.01)


@pytest.mark.parametrize("every", [1, 3])
def test_samples_kept_one_step_at_a_time_equal_those_of_a_block(every):
    """A watched run keeps its states one step at a time (put_span of one row, a path without the block's index
    arrays): the kept times, steps and states equal those of one block, the shortened last step included."""
    from pinstab.integration.records import Records
    from pinstab.integration.stepping import TimeGrid

    grid = TimeGrid.of(0.1, 1.05, every)
    states = np.arange(grid.steps + 1, dtype=float)[:, None] * [1.0, -2.0]
    one, block = Records(grid, every, 2, 2), Records(grid, every, 2, 2)
    for k in range(grid.steps + 1):
        one.put_span(k, states[k : k + 1], -states[k : k + 1])
    block.put_span(0, states, -states)
    assert grid.steps == 11 and np.array_equal(one.steps, block.steps) and np.array_equal(one.t, block.t)
    assert np.array_equal(one.q, block.q) and np.array_equal(one.v, block.v)
    assert one.t[one.last] == pytest.approx(1.05) and one.q[one.last, 0] == 11.0
