"""Trajectory error as output: exact references, saved references, named coordinates, the JSON and the chart."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from pinstab import ConstrainedModel, PinstabError, load_scene, simulate, trajectory_error
from pinstab.analysis import EXACT_REFERENCES, exact_reference
from pinstab.cli import main
from pinstab.integration.dense import Segment
from pinstab.trajectory import Trajectory
from pinstab.viz.plots import trajectory_figure


@pytest.fixture(scope="module")
def nfourbar_run():
    scene = load_scene("nfourbar", N=3)
    return scene, simulate(scene, method="projection", dt=1e-3, duration=1.5)


def test_nfourbar_error_is_the_crank_angle_against_the_pendulum_written_out(nfourbar_run):
    """The registered exact motion of N = 3 against the pendulum J th'' = K sin th written out here: the
    reported crank error is |th_run - th| to 1e-11 rad, and every coupler joint sits at -th."""
    scene, run = nfourbar_run
    n, g = 3, 9.81
    inertia, stiffness = (n + 1) / 3 + n, g * ((n + 1) / 2 + n)
    exact = solve_ivp(
        lambda t, y: [y[1], stiffness * np.sin(y[0]) / inertia],
        (0, run.t[-1]),
        [0.0, -1.0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
        t_eval=run.t,
    ).y[0]
    comparison = trajectory_error(run, "exact", scene=scene)
    assert comparison.names == ["crank0_joint"] and comparison.units == ["rad"]
    np.testing.assert_allclose(comparison.error[:, 0], np.abs(run.q[:, 0] - exact), rtol=0, atol=1e-11)
    reference = exact_reference(scene, run.q[0], run.v[0], run.t)
    coupler = scene.model.joints[scene.model.getJointId("coupler2_joint")].idx_q
    np.testing.assert_allclose(reference.q[:, coupler], -exact, rtol=0, atol=1e-11)
    assert comparison.error.max() < 1e-8 and exact.min() < -np.pi / 2  # through one singular passage


def test_a_run_against_itself_saved_is_exact_and_against_a_finer_run_close_to_the_exact_error(tmp_path):
    """A saved run as reference: itself gives 0; a finer run (0.25 ms, error 4^4 smaller) whose samples
    are not the run's times (Hermite between them) gives the run's exact error within 5 %."""
    scene = load_scene("fourbar")
    coarse = simulate(scene, method="projection", dt=6e-3, duration=1.2)
    coarse.save(tmp_path / "coarse.npz")
    assert trajectory_error(coarse, tmp_path / "coarse.npz", scene=scene).error.max() == 0.0
    fine = simulate(scene, method="projection", dt=2.5e-4, duration=1.2, record_every=7)  # 1.75 ms samples
    assert not np.isin(np.round(coarse.t[1:-1], 9), np.round(fine.t, 9)).all()
    against_fine = trajectory_error(coarse, fine, of=["joints"], scene=scene).error[:, 0]
    against_exact = trajectory_error(coarse, "exact", of=["joints"], scene=scene).error[:, 0]
    assert against_exact.max() > 1e-7
    assert abs(against_fine.max() - against_exact.max()) < 0.05 * against_exact.max()


def test_cubic_dense_output_of_samples_converges_at_order_four():
    """Between two samples (q, v) of the motion q(t) = sin(3t) of every joint, the cubic Hermite error
    falls 16x per halved span (measured 15.9)."""
    model = ConstrainedModel(load_scene("fourbar"))
    errors = []
    for h in (0.1, 0.05):
        ends = [(t, np.full(3, np.sin(3 * t)), np.full(3, 3 * np.cos(3 * t))) for t in (0.2, 0.2 + h)]
        span = Segment(model, *ends[0], None, *ends[1], None)
        middle = 0.2 + h / 2
        errors.append(abs(span.state(middle)[0][0] - np.sin(3 * middle)))
    assert 14 < errors[0] / errors[1] < 18


def test_frame_error_is_the_distance_of_frame_origins(nfourbar_run):
    """Coupler 3's origin sits on crank 2's tip: its error is the chord 2 L sin(dth / 2) of the crank error."""
    scene, run = nfourbar_run
    comparison = trajectory_error(run, "exact", of=["coupler3", "crank2_joint"], scene=scene)
    chord = 2 * np.sin(comparison.error[:, 1] / 2)
    np.testing.assert_allclose(comparison.error[:, 0], chord, rtol=1e-6, atol=1e-15)
    assert comparison.units == ["m", "rad"]


@pytest.mark.parametrize(
    ("reference", "of", "message"),
    [
        ("exact", ["nope"], "no joint or frame named 'nope'.*joints: crank0_joint"),
        ("exact", ["crank9_joint"], "no joint or frame named 'crank9_joint'"),
    ],
)
def test_unknown_coordinates_are_refused_naming_the_joints(nfourbar_run, reference, of, message):
    scene, run = nfourbar_run
    with pytest.raises(PinstabError, match=message):
        trajectory_error(run, reference, of=of, scene=scene)


def test_references_that_do_not_fit_are_refused(nfourbar_run, tmp_path):
    scene, run = nfourbar_run
    with pytest.raises(PinstabError, match="scene 'fivebar' has no exact reference; scenes with one: fourbar"):
        trajectory_error(simulate(load_scene("fivebar"), duration=0.01))
    other = simulate(load_scene("nfourbar", N=2), dt=1e-3, duration=0.1)
    with pytest.raises(PinstabError, match=r"a run of 'nfourbar' \(N=2\), this run is of 'nfourbar' \(N=3\)"):
        trajectory_error(run, other, scene=scene)
    short = simulate(scene, dt=1e-3, duration=0.5)
    with pytest.raises(PinstabError, match="ends at t = 0.5 s, before this run's last sample at 1.5 s"):
        trajectory_error(run, short, scene=scene)
    q, v = run.q[0].copy(), run.v[0].copy()
    v[scene.model.joints[scene.model.getJointId("crank2_joint")].idx_v] += 1e-3
    with pytest.raises(PinstabError, match="joint 'crank2_joint' starts 0.001 off it"):
        exact_reference(scene, q, v, run.t)
    assert set(EXACT_REFERENCES) == {"fourbar", "nfourbar", "stiff-fourbar"}


def test_comparison_is_saved_loaded_and_charted(nfourbar_run, tmp_path):
    """The comparison survives --save/load, and the chart's error panel spans the positive errors only."""
    scene, run = nfourbar_run
    run.comparison = trajectory_error(run, "exact", of=["crank0_joint", "joints"], scene=scene)
    path = run.save(tmp_path / "run.npz")
    loaded = Trajectory.load(path)
    np.testing.assert_array_equal(loaded.comparison.error, run.comparison.error)
    assert loaded.comparison.names == ["crank0_joint", "joints"]
    figure = trajectory_figure(loaded)
    error_axis = figure.axes[-1]
    assert error_axis.get_ylabel() == "trajectory error" and error_axis.get_yscale() == "log"
    low, high = error_axis.get_ylim()
    positive = run.comparison.error[run.comparison.error > 0]
    assert positive.min() / 10 < low <= positive.min() and positive.max() <= high < positive.max() * 10


def test_drift_panel_spans_the_positive_drift_only():
    """A run whose drift starts at exactly 0: the log axis starts within a decade of the smallest positive
    drift, not at 1e-300 (item 9)."""
    run = simulate(load_scene("fourbar"), method="projection", dt=1e-3, duration=0.2)
    drift = {name: getattr(run, name).copy() for name in ("position_drift", "velocity_drift")}
    for series in drift.values():
        series[:3] = 0.0
    copy = Trajectory(run.t, run.q, run.v, 0.0, run.info, energy=run.energy, multipliers=run.multipliers, **drift)
    low, _ = trajectory_figure(copy).axes[0].get_ylim()
    smallest = min(d[d > 0].min() for d in drift.values())
    assert smallest / 10 < low <= smallest


def test_cli_prints_the_error_and_refuses_bad_references_before_running(capsys, tmp_path):
    code = main(["run", "fourbar", "--duration", "1", "--reference", "exact", "--json", "--quiet"])
    block = json.loads(capsys.readouterr().out)["trajectory_error"]
    assert code == 0 and block["reference"].startswith("exact: the crank-angle equation")
    assert block["coordinates"]["crank"]["unit"] == "rad" and 1e-9 < block["max"] < 1e-5
    for argv, message in (
        (["--reference", "exact", "--error-of", "nope"], "no joint or frame named 'nope'"),
        (["--reference", str(tmp_path / "none.npz")], "does not exist"),
        (["--error-of", "crank"], "give --reference exact or RUN.npz"),
    ):
        assert main(["run", "fourbar", "--duration", "1e9", *argv, "--quiet"]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, err


def test_group_difference_is_used_for_joint_errors():
    """On a free-flyer the joint error is the tangent-space distance (pin.difference), not |q - q_ref|."""
    model = pin.buildSampleModelHumanoid()
    q_ref = pin.neutral(model)
    step = np.zeros(model.nv)
    step[3:6] = [0.0, 0.0, 0.2]
    q = pin.integrate(model, q_ref, step)
    from pinstab.analysis.error import coordinate_measure

    measure, unit = coordinate_measure(model, "root_joint")
    assert abs(measure(q, q_ref) - 0.2) < 1e-12 and unit == "rad"
