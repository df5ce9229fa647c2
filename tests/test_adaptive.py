"""Error control (--rtol/--atol): accuracy follows the tolerance, the counters are the work done, bad
requests are refused, and the samples on the grid come from the dense output."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pinstab import PinstabError, load_scene, simulate, trajectory_error
from pinstab.cli import main


@pytest.fixture(scope="module")
def fourbar():
    return load_scene("fourbar")


def test_error_follows_the_tolerance_on_the_fourbar(fourbar):
    """Against the exact crank-angle equation over 10 s: rtol 1e-8 reaches <= 1e-6 rad (measured 6.7e-7),
    and each factor 100 on rtol brings the error down by 30x at least (measured 290x and 63x)."""
    errors = {}
    for rtol in (1e-6, 1e-8, 1e-10):
        run = simulate(fourbar, method="baumgarte", integrator="dop853", rtol=rtol, dt=1e-2, duration=10.0)
        errors[rtol] = trajectory_error(run, "exact", scene=fourbar).error.max()
    assert errors[1e-8] <= 1e-6
    assert errors[1e-6] > 30 * errors[1e-8] > 30 * 30 * errors[1e-10]


def test_counters_are_the_work_done(fourbar):
    """DOP853 with FSAL: 12 evaluations per attempted step after the first (13), plus the initial step's
    2 and one per dense-output end; the counts add up and the JSON carries them."""
    run = simulate(fourbar, method="baumgarte", integrator="dop853", rtol=1e-8, dt=1e-2, duration=2.0)
    control = run.info.error_control
    attempts = control["steps_accepted"] + control["steps_rejected"]
    evaluations = run.summary()["dynamics_evaluations"]
    assert control["steps_accepted"] > 20 and 11 * attempts <= evaluations <= 14 * attempts + 10
    assert 0 < control["smallest_step"] <= control["largest_step"]
    assert len(run.t) == 201 and np.allclose(np.diff(run.t), 1e-2)  # the samples on the --dt grid


def test_dense_output_samples_agree_with_the_steps_ends(fourbar):
    """The grid samples between accepted steps come from the quintic Hermite interpolant: with the output
    grid ten times finer, the error against the exact motion stays at the step's accuracy (within 3x)."""
    coarse = simulate(fourbar, method="projection", integrator="dop853", rtol=1e-9, dt=1e-2, duration=3.0)
    fine = simulate(fourbar, method="projection", integrator="dop853", rtol=1e-9, dt=1e-3, duration=3.0)
    coarse_error = trajectory_error(coarse, "exact", scene=fourbar).error.max()
    fine_error = trajectory_error(fine, "exact", scene=fourbar).error.max()
    assert fine_error < 3 * coarse_error + 1e-9


def test_dopri5_is_less_efficient_but_converges(fourbar):
    run = simulate(fourbar, method="projection", integrator="dopri5", rtol=1e-7, dt=1e-2, duration=3.0)
    assert trajectory_error(run, "exact", scene=fourbar).error.max() < 1e-4


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"integrator": "rk4", "rtol": 1e-6}, "integrator 'rk4' has no error estimator for rtol/atol"),
        ({"method": "mukharlyamov", "integrator": "dop853", "rtol": 1e-6}, "places its automatic gains"),
        ({"integrator": "dop853", "rtol": 1e-20}, r"rtol must be a number in \(1e-14, 1\), got 1e-20"),
        ({"integrator": "dop853", "rtol": 1e-6, "atol": -1.0}, r"atol must be a number in \(0, 1\), got -1"),
    ],
)
def test_bad_error_control_is_refused(fourbar, options, message):
    with pytest.raises(PinstabError, match=message):
        simulate(fourbar, duration=0.1, **options)


@pytest.mark.parametrize("tolerance", [{"rtol": 1e-8}, {"atol": 1e-8}])
def test_a_tolerance_without_an_integrator_picks_dop853_as_the_cli_does(fourbar, capsys, tolerance):
    """simulate(rtol=...) or (atol=...) without an integrator runs dop853 (it refused rk4, its old default, here):
    the very run of integrator="dop853", within 1e-6 rad of the exact crank angle; ``--rtol``/``--atol`` on the
    command line take the same rule and give the same run."""
    run = simulate(fourbar, dt=1e-2, duration=2.0, **tolerance)
    named = simulate(fourbar, integrator="dop853", dt=1e-2, duration=2.0, **tolerance)
    assert run.info.integrator == "dop853" and run.info.error_control == named.info.error_control
    assert np.array_equal(run.q, named.q)
    assert trajectory_error(run, "exact", scene=fourbar).error.max() <= 1e-6
    ((flag, value),) = tolerance.items()
    argv = ["run", "fourbar", f"--{flag}", str(value), "--dt", "1e-2", "--duration", "2", "--json", "--quiet"]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["integrator"] == "dop853" and result["error_control"] == named.info.error_control


def test_cli_rtol_defaults_to_dop853_and_reports_the_control(capsys):
    assert main(["run", "fourbar", "--rtol", "1e-8", "--duration", "1", "--json", "--quiet"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["integrator"] == "dop853" and result["error_control"]["rtol"] == 1e-8
    assert result["error_control"]["steps_accepted"] > 0 and result["dynamics_evaluations"] > 0


def test_a_stage_that_loses_the_grasp_rejects_the_step():
    """allegro-sphere under error control: the first steps grow until a trial step's stage overshoots and finds a
    fingertip outside its cone (the run ended there, "grasp lost at t = 0.03 s"); that step is rejected like one
    with a non-finite error, and the run's contact forces agree with the fixed-step RK4 run at 1 ms (1e-5 N over
    0.2 s; its error is 1e-7 N, benchmarks/grasp_admm.py)."""
    scene = load_scene("allegro-sphere")
    adaptive = simulate(scene, "baumgarte", "dop853", 0.01, 0.2, rtol=1e-6)
    fixed = simulate(scene, "baumgarte", "rk4", 1e-3, 0.2, record_every=10)
    assert adaptive.info.error_control["steps_rejected"] > 0
    assert np.abs(adaptive.multipliers - fixed.multipliers).max() < 1e-5
