"""Benchmark machinery: distributed sweeps equal serial ones, outputs written, peers measured alike.

No timing is asserted here (timings are benchmark output, not test material)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pinstab import load_scene, simulate
from pinstab.assembly import assemble
from pinstab.bench.overhead import KD, KP
from pinstab.bench.peers import STEP_SCHEMES, native_pinocchio
from pinstab.bench.workprecision import (
    Config,
    Reference,
    Result,
    cheapest_within,
    check_sweep,
    default_configs,
    reference_motion,
    run_config,
    sweep,
    write_outputs,
)
from pinstab.cli import main
from pinstab.errors import PinstabError
from pinstab.model import ConstrainedModel

CONFIGS = [
    Config("baumgarte", "semi-implicit-euler", 2e-3),
    Config("projection", "rk4", 2e-3),
    Config("pinocchio-native", "semi-implicit-euler", 2e-3, "pinocchio-native", 10.0, 2 * math.sqrt(10.0)),
]
FIGURES = ("max_position_drift", "max_velocity_drift", "trajectory_error", "energy_error")


def test_distributed_results_equal_serial_results():
    _, serial = sweep("fourbar", {}, CONFIGS, 0.1, serial=True)
    _, distributed = sweep("fourbar", {}, CONFIGS, 0.1)
    for a, b in zip(serial, distributed, strict=True):
        assert a.config == b.config
        for name in FIGURES:
            assert getattr(a, name) == getattr(b, name), (a.config.curve, name)


def test_fourbar_reference_is_independent_and_agrees_with_pinstab():
    """The crank-angle equation (closed-form loop geometry, no constraint solver) and pinstab's
    projection + dop853 on the URDF model are two methods for one motion: within 1e-9 rad over 2 s
    (measured 6e-12 against projection + RK4 at 0.1 ms)."""
    from pinstab import load_scene, simulate
    from pinstab.analysis.fourbar import fourbar_motion

    scene = load_scene("fourbar")
    run = simulate(scene, "projection", "dop853", 1e-3, 2.0)
    np.testing.assert_allclose(fourbar_motion(scene, run.q[0], run.v[0], run.t).q, run.q, rtol=0, atol=1e-9)


def test_reference_and_errors_behave():
    """The four-bar's reference is its independent crank-angle model: rk4 at dt is far closer to it
    than semi-implicit Euler at the same dt, and the hand-written Pinocchio loop is measured on the same
    scale (with the same corrector and scheme it is the same motion as pinstab's, SIE and RK4)."""
    reference, results = sweep("fourbar", {}, CONFIGS, 0.2, serial=True)
    assert reference.kind.startswith("exact: the crank-angle equation")
    by_curve = {r.config.curve: r for r in results}
    assert (
        by_curve["projection + rk4"].trajectory_error
        < 1e-3 * by_curve["baumgarte + semi-implicit-euler"].trajectory_error
    )
    native = by_curve["pinocchio-native Kp=10 + semi-implicit-euler"]
    baumgarte_same_gains = run_config(
        "fourbar", {}, Config("pinocchio", "semi-implicit-euler", 2e-3, kp=10.0, kd=2 * math.sqrt(10.0)), 0.2, reference
    )
    # the same corrector and scheme inside pinstab and in Pinocchio's own loop: the same motion
    assert native.trajectory_error == pytest.approx(baumgarte_same_gains.trajectory_error, rel=1e-6)
    assert np.isfinite(native.cpu_per_sim_s) and native.cpu_per_sim_s > 0
    hand_rk4, ours_rk4 = (
        run_config("fourbar", {}, config, 0.2, reference)
        for config in (
            Config("pinocchio-native", "rk4", 2e-3, "pinocchio-native", 100.0, 20.0),
            Config("baumgarte", "rk4", 2e-3, kp=100.0, kd=20.0),
        )
    )
    assert hand_rk4.trajectory_error == pytest.approx(ours_rk4.trajectory_error, rel=1e-6)


def test_default_configs_give_the_peers_their_best():
    """The hand-written loop: semi-implicit Euler and RK4, four gains, steps down to 0.25 ms; MuJoCo:
    Euler, implicitfast and RK4 down to 1e-5 s with solref 2 dt."""
    configs = default_configs(["baumgarte"], ["rk4"], [1e-3, 2e-3])
    native = [c for c in configs if c.peer == "pinocchio-native"]
    assert {(c.kp, c.kd) for c in native} >= {(10.0, 2 * math.sqrt(10.0)), (1e4, 200.0)}
    assert {c.integrator for c in native} == {"semi-implicit-euler", "rk4"} and min(c.dt for c in native) == 2.5e-4
    mujoco = [c for c in configs if c.peer == "mujoco"]
    if mujoco:
        assert {c.integrator for c in mujoco} == {"euler", "implicitfast", "rk4"} and min(c.dt for c in mujoco) == 1e-5
        assert all(c.solref == (2 * c.dt, 1.0) for c in mujoco)
    assert sum(c.peer is None and c.rtol is None for c in configs) == 2


def test_bench_cli_writes_tables_and_charts(tmp_path, capsys):
    out = tmp_path / "bench"
    argv = ["bench", "fourbar", "--methods", "baumgarte", "--integrators", "rk4", "--dts", "4e-3", "--duration", "0.1"]
    assert main([*argv, "-o", str(out), "--serial", "--json", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["overhead_ratio"] > 0 and summary["reference"].startswith("exact: the crank-angle equation")
    for name in ("results.json", "results.csv", "work_precision.png", "drift.png"):
        assert (out / name).stat().st_size > 0
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 1 + len(default_configs(["baumgarte"], ["rk4"], [4e-3]))  # header + one row per run


def test_the_drift_chart_takes_the_smallest_step_that_has_a_drift_series(tmp_path, monkeypatch):
    """A sweep whose smallest step has no drift series (MuJoCo's runs at 0.01 ms) draws the drift of the smallest
    step that has one (it drew an empty chart); a sweep without any draws none."""
    import pinstab.plotting

    drawn, save = [], pinstab.plotting.save_figure

    def keep(fig, path):  # the drift chart's curves: (label, samples)
        if path.name == "drift.png":
            drawn.extend((line.get_label(), len(line.get_xdata())) for line in fig.axes[0].get_lines())
        return save(fig, path)

    monkeypatch.setattr(pinstab.plotting, "save_figure", keep)
    reference = Reference("exact", np.array([0.0, 1.0]), np.zeros((2, 1)), 1e-3)
    ours = [
        Result(
            Config("baumgarte", "rk4", dt), 1.0, trajectory_error=1e-6, drift_series=[1e-9] * n, drift_times=[0.0] * n
        )
        for dt, n in ((1e-3, 3), (5e-4, 5))
    ]
    peer = Result(Config("mujoco", "euler", 1e-5, "mujoco", solref=(2e-5, 1.0)), 2.0, trajectory_error=1e-3)
    write_outputs(tmp_path / "a", "nfourbar", reference, [*ours, peer], {"duration": 1.0})
    assert drawn == [("baumgarte + rk4", 5)] and (tmp_path / "a" / "drift.png").stat().st_size > 0
    write_outputs(tmp_path / "b", "nfourbar", reference, [peer], {"duration": 1.0})
    assert not (tmp_path / "b" / "drift.png").exists() and (tmp_path / "b" / "results.md").exists()


def test_bench_refuses_bad_input(capsys):
    assert main(["bench", "fourbar", "--dts", "-1", "-o", "/tmp/x", "--serial"]) == 2
    assert "--dts" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("configs", "duration", "message"),
    [
        ([], 1.0, "no configuration to run"),
        (CONFIGS, 0.0, "duration must be a positive number of seconds, got 0.0"),
        (CONFIGS, math.nan, "got nan"),
        ([Config("baumgarte", "rk4", math.inf)], 1.0, "step inf s of baumgarte \\+ rk4 must be a positive number"),
        ([Config("baumgarte", "rk4", 10.0)], 1.0, "is longer than the duration 1 s"),
        ([Config("baumgarte", "rk4", 5e-324)], 1.0, "makes inf steps, more than the 1e\\+08 a run takes"),
        (CONFIGS, 1e308, "0.0001 s \\(the runs' or the reference's\\)"),
    ],
)
def test_sweeps_out_of_range_are_refused_before_any_run(configs, duration, message):
    with pytest.raises(PinstabError, match=message):
        check_sweep(configs, duration)
    with pytest.raises(PinstabError, match=message):
        sweep("fourbar", {}, configs, duration, serial=True)


def test_cheapest_within_refuses_a_tolerance_that_is_not_positive():
    with pytest.raises(PinstabError, match="tolerance must be a positive number"):
        cheapest_within([], -1.0, None)


def test_mujoco_peer_models_the_same_mechanism():
    """The MJCF written from the scene (same tree, inertias, closure as a connect equality) moves like
    pinstab's model: with a stiff solref its four-bar stays within 1e-3 rad of the reference over 1 s
    (measured 3.1e-4), and the default solref (softer) drifts more."""
    pytest.importorskip("mujoco")
    reference, results = sweep(
        "fourbar",
        {},
        [Config("mujoco", "rk4", 1e-3, "mujoco", solref=s) for s in ((0.002, 1.0), (0.02, 1.0))],
        1.0,
        serial=True,
    )
    stiff, default = results
    assert stiff.trajectory_error < 1e-3
    assert default.max_position_drift > 10 * stiff.max_position_drift


def test_cheapest_within_picks_per_peer():
    from pinstab.bench.workprecision import Result, cheapest_within

    runs = [
        Result(Config("projection", "rk4", 2e-3), cpu_per_sim_s=0.5, trajectory_error=5e-7),
        Result(Config("baumgarte", "rk4", 4e-3), cpu_per_sim_s=0.2, trajectory_error=1e-3),
        Result(Config("mujoco", "rk4", 1e-3, "mujoco", solref=(0.002, 1.0)), cpu_per_sim_s=0.03, trajectory_error=4e-2),
        Result(
            Config("pinocchio-native", "semi-implicit-euler", 1e-3, "pinocchio-native", 10.0, 6.3),
            cpu_per_sim_s=0.01,
            trajectory_error=5e-7,
            diverged=True,
        ),
    ]
    assert cheapest_within(runs, 1e-6, None).config.method == "projection"
    assert cheapest_within(runs, 1e-6, "mujoco") is None  # never reaches the tolerance
    assert cheapest_within(runs, 1e-6, "pinocchio-native") is None  # diverged runs do not count
    assert cheapest_within(runs, 1e-1, "mujoco").cpu_per_sim_s == 0.03


def test_native_peer_applies_the_scene_forces():
    """slider-crank (motor + damper): Pinocchio's own loop and pinstab's pinocchio method, same gains
    and scheme, produce the same motion, so the peer simulates the same system."""
    reference, results = sweep(
        "slider-crank",
        {},
        [
            Config("pinocchio-native", "semi-implicit-euler", 2e-3, "pinocchio-native", 10.0, 2 * math.sqrt(10.0)),
            Config("pinocchio", "semi-implicit-euler", 2e-3, kp=10.0, kd=2 * math.sqrt(10.0)),
        ],
        0.5,
        serial=True,
    )
    native, ours = results
    assert native.trajectory_error == pytest.approx(ours.trajectory_error, rel=1e-6)


def test_scipy_peer_is_dop853_over_pinocchio_and_meets_its_tolerance():
    """SciPy's DOP853 on y' = (v, constraintDynamics) at rtol 1e-10 over 1 s: within 1e-7 rad of the
    four-bar's exact motion (an independent model), its evaluations counted; a tighter rtol costs more
    evaluations and gives a smaller error."""
    from pinstab.bench.scipy_peer import SCIPY_PEER

    reference = reference_motion("fourbar", {}, 1.0)
    runs = [
        run_config("fourbar", {}, Config(SCIPY_PEER, "dop853", 1e-2, SCIPY_PEER, 0.0, 0.0, rtol=rtol), 1.0, reference)
        for rtol in (1e-7, 1e-10)
    ]
    assert not any(run.diverged for run in runs)
    assert runs[1].trajectory_error < 1e-7 and runs[1].trajectory_error < runs[0].trajectory_error / 10
    assert runs[1].evaluations > runs[0].evaluations > 100
    row = runs[1].row()
    assert row["rtol"] == 1e-10 and row["curve"] == "scipy-dop853 Kp=0" and row["evaluations"] == runs[1].evaluations


def test_error_controlled_configs_and_the_cheapest_table():
    """default_configs adds pinstab's dop853 --rtol runs and the SciPy peer at every rtol; the table names
    the cheapest of each and the ratios."""
    from pinstab.bench.workprecision import RTOLS, Result, cheapest_table

    configs = default_configs(["baumgarte"], ["rk4"], [1e-3], mujoco=False)
    assert {c.rtol for c in configs if c.peer is None and c.rtol is not None} == set(RTOLS)
    assert {(c.kp, c.rtol) for c in configs if c.peer == "scipy-dop853"} >= {(0.0, 1e-9), (100.0, 1e-5)}
    runs = [
        Result(Config("baumgarte", "dop853", 1e-2, rtol=1e-8), cpu_per_sim_s=0.01, trajectory_error=5e-7),
        Result(Config("baumgarte", "rk4", 1e-3), cpu_per_sim_s=0.02, trajectory_error=6e-7),
        Result(Config("scipy-dop853", "dop853", 1e-2, "scipy-dop853", 0.0, 0.0, rtol=1e-9), 0.04, 0, 0, 4e-7),
    ]
    table = cheapest_table(runs, 1e-6)
    assert table["pinstab-rtol"]["rtol"] == 1e-8 and table["pinstab-fixed-step"]["integrator"] == "rk4"
    assert table["cost_ratio_pinstab_rtol_over_scipy-dop853"] == pytest.approx(0.25)
    assert table["mujoco"] is None and table["cost_ratio_pinstab_over_mujoco"] is None


def test_bad_rtols_are_refused(capsys):
    assert main(["bench", "fourbar", "--rtols", "0", "-o", "/tmp/x", "--serial"]) == 2
    assert "--rtols: tolerances must be in" in capsys.readouterr().err
    with pytest.raises(PinstabError, match=r"rtol 2.0 of baumgarte \+ dop853 \(rtol\) must be a number in"):
        check_sweep([Config("baumgarte", "dop853", 1e-2, rtol=2.0)], 1.0)


@pytest.mark.parametrize("scheme", STEP_SCHEMES)
def test_hand_written_loops_are_the_schemes_simulate_runs(scheme):
    """The overhead benchmark's hand-written Pinocchio loops step as ``simulate()`` does with the same
    scheme, step and gains (four-bar, native path, 0.2 s: to 1e-12 rad), so its ratios compare like with
    like."""
    scene = load_scene("fourbar")
    start = assemble(ConstrainedModel(scene), scene.q0, scene.v0)
    ours = simulate(scene, "baumgarte", scheme, 1e-3, 0.2, kp=KP, kd=KD)
    q, _, _ = native_pinocchio(scene, start.q, start.v, 1e-3, 200, KP, KD, scheme)
    assert ours.info.path == "native"
    np.testing.assert_allclose(ours.q, q, rtol=0, atol=1e-12)
