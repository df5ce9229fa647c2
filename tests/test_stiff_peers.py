"""The peers of the stiff mechanism (issue 37): SciPy's Radau and BDF over Pinocchio and MuJoCo's integrators on
``stiff-fourbar`` against its exact reference (SciPy Radau at 1e-12 on the spring chain written with Pinocchio alone:
another right-hand side than the peers'), ``pinstab bench`` with them, and benchmarks/stiff_fourbar.py's rows.

Errors measured (0.2 s, samples every 1 ms): Radau at rtol 1e-8 6.0e-10 rad, BDF at rtol 1e-10 1.4e-9 rad; MuJoCo RK4
at 1e-5 s 3.8e-10 rad, implicitfast 3.0e-4 rad at 1e-4 s and 2.9e-5 rad at 1e-5 s (first order).
"""

from __future__ import annotations

import importlib.util
import json
import tomllib

import pytest

from conftest import ROBOTS
from pinstab import PinstabError
from pinstab.bench.scipy_peer import run_scipy
from pinstab.bench.workprecision import ADAPTIVE_OUTPUT_STEP, Config, reference_motion, run_config
from pinstab.cli import main
from pinstab.integration import INTEGRATORS
from pinstab.integration.schemes import RK4, DormandPrince5
from pinstab.scene import load_scene, scene_from_dict

SCENE = "stiff-fourbar"
DURATION = 0.2  # [s]
BENCHMARK = ROBOTS.parent / "benchmarks" / "stiff_fourbar.py"


@pytest.fixture(scope="module")
def reference():
    """The exact motion over DURATION, sampled every 1 ms."""
    return reference_motion(SCENE, {}, DURATION, exact_step=1e-3)


def scipy_config(peer: str, rtol: float) -> Config:
    return Config(peer, peer.removeprefix("scipy-"), ADAPTIVE_OUTPUT_STEP, peer, 0.0, 0.0, rtol=rtol)


@pytest.mark.parametrize(("peer", "rtol", "bound"), [("scipy-radau", 1e-8, 5e-9), ("scipy-bdf", 1e-10, 1e-8)])
def test_implicit_scipy_peer_follows_the_exact_motion(reference, peer, rtol, bound):
    """Radau within 5e-9 rad at rtol 1e-8 (measured 6.0e-10), BDF within 1e-8 rad at rtol 1e-10 (1.4e-9): the
    peer's spring is the scene's (a peer without it would be off by radians); a looser tolerance costs fewer
    evaluations (the Jacobian's included) for a larger error."""
    tight = run_config(SCENE, {}, scipy_config(peer, rtol), DURATION, reference)
    loose = run_config(SCENE, {}, scipy_config(peer, 1e-4), DURATION, reference)
    assert not tight.diverged and tight.trajectory_error < bound
    assert loose.trajectory_error > 10 * tight.trajectory_error
    assert tight.evaluations > loose.evaluations > 50
    assert tight.row()["curve"] == f"{peer} Kp=0"


def test_unknown_scipy_peer_is_refused_naming_the_peers():
    scene = load_scene(SCENE)
    with pytest.raises(PinstabError, match="scipy-lsoda.*scipy-bdf, scipy-dop853, scipy-radau"):
        run_scipy(scene, scene.q0, scene.v0, 1e-3, 10, 0.0, 0.0, 1e-6, "scipy-lsoda")


def test_mujoco_models_the_stiff_mechanism(reference):
    """The MJCF (same tree and inertias, the spring-damper as a spatial tendon with stiffness, damping and
    springlength) with RK4 at 1e-5 s within 1e-8 rad of the reference (measured 3.8e-10); implicitfast converges to
    it at first order: its error shrinks 8-12x from 1e-4 s to 1e-5 s (measured 10.1x)."""
    pytest.importorskip("mujoco")

    def error(scheme: str, dt: float) -> float:
        result = run_config(
            SCENE, {}, Config("mujoco", scheme, dt, "mujoco", solref=(2 * dt, 1.0)), DURATION, reference
        )
        assert not result.diverged
        return result.trajectory_error

    assert error("rk4", 1e-5) < 1e-8
    coarse, fine = error("implicitfast", 1e-4), error("implicitfast", 1e-5)
    assert 8 < coarse / fine < 12 and fine < 1e-4


def test_mujoco_run_that_goes_unstable_is_a_divergence(reference, tmp_path, monkeypatch):
    """RK4 at 1 ms (above its stability limit 0.31 ms): MuJoCo resets a non-finite state and goes on; the peer stops
    the run as diverged with MuJoCo's warning instead of measuring the restarted motion, and writes no
    MUJOCO_LOG.TXT."""
    pytest.importorskip("mujoco")
    monkeypatch.chdir(tmp_path)
    result = run_config(SCENE, {}, Config("mujoco", "rk4", 1e-3, "mujoco", solref=(2e-3, 1.0)), DURATION, reference)
    assert result.diverged and "went unstable: Nan, Inf or huge value" in result.note
    assert not list(tmp_path.iterdir())


def test_mujoco_peer_refuses_a_force_element_it_has_no_counterpart_for():
    """A joint spring is not written into the MJCF: the peer refuses the scene naming the element rather than
    simulating another system."""
    pytest.importorskip("mujoco")
    from pinstab.bench.mujoco_peer import run_mujoco

    data = tomllib.loads((ROBOTS / "stiff-fourbar.toml").read_text())
    data["forces"].append({"name": "crank-spring", "kind": "joint-spring", "joint": "crank", "stiffness": 3.0})
    scene = scene_from_dict(data, base_dir=ROBOTS, name="stiff-fourbar-joint-spring")
    with pytest.raises(PinstabError, match="'crank-spring' has no MJCF counterpart"):
        run_mujoco(scene, scene.q0, scene.v0, 1e-4, 10, "implicitfast", (2e-4, 1.0))


def test_bench_runs_the_implicit_peers_on_the_stiff_mechanism(tmp_path, capsys):
    """``pinstab bench stiff-fourbar`` over 0.05 s: SciPy's Radau, BDF and DOP853 are in the results within 1e-6 rad
    of the reference at rtol 1e-8, at Kp = 0 only (no constraints: no gain to sweep), and in the cheapest table;
    MuJoCo's implicitfast at 1e-5 s within 1e-4 rad (its first order)."""
    pytest.importorskip("mujoco")
    argv = ["bench", SCENE, "-o", str(tmp_path), "--serial", "--duration", "0.05", "--methods", "baumgarte"]
    argv += ["--integrators", "rk4", "--dts", "1e-4", "--peer-dts", "1e-4", "--mujoco-dts", "1e-5", "--rtols", "1e-8"]
    assert main(argv) == 0
    summary = json.loads((tmp_path / "results.json").read_text())
    rows = {(row["peer"], row["integrator"]): row for row in summary["results"]}
    for key in (("scipy-radau", "radau"), ("scipy-bdf", "bdf"), ("scipy-dop853", "dop853")):
        assert not rows[key]["diverged"] and rows[key]["trajectory_error"] < 1e-6, key
    assert 1e-6 < rows["mujoco", "implicitfast"]["trajectory_error"] < 1e-4  # first order (measured 1.3e-5)
    assert {row["kp"] for row in summary["results"] if row["peer"] and row["peer"] != "mujoco"} == {0.0}
    assert summary["cheapest"]["scipy-radau"]["integrator"] == "radau"
    assert summary["cheapest"]["cost_ratio_pinstab_over_scipy-bdf"] > 0


@pytest.fixture
def benchmark():
    """benchmarks/stiff_fourbar.py as a module."""
    spec = importlib.util.spec_from_file_location("stiff_fourbar_benchmark", BENCHMARK)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def implicit_stand_ins():
    """Two integrators registered as implicit for the benchmark's rows: RK4's step (fixed) and DOPRI5's pair
    (embedded), unregistered after."""
    fixed = type("FixedStandIn", (RK4,), {"implicit": True})
    embedded = type("EmbeddedStandIn", (DormandPrince5,), {"implicit": True})
    INTEGRATORS.register("stand-in-fixed", fixed, summary="test")
    INTEGRATORS.register("stand-in-pair", embedded, summary="test")
    yield
    INTEGRATORS.unregister("stand-in-fixed")
    INTEGRATORS.unregister("stand-in-pair")


def test_benchmark_rows_take_every_implicit_integrator(benchmark, implicit_stand_ins):
    """Registered implicit integrators join the benchmark's implicit group: the embedded ones over its
    tolerances, the fixed-step ones over its steps; the explicit group keeps rk4, dopri5 and dop853."""
    rows = benchmark.configurations()
    implicit = {label: config for label, (group, config) in rows.items() if group == "pinstab implicit"}
    assert {c.rtol for c in implicit.values() if c.integrator == "stand-in-pair"} == set(benchmark.RTOLS)
    assert {c.dt for c in implicit.values() if c.integrator == "stand-in-fixed"} == set(benchmark.IMPLICIT_DTS)
    stand_ins = [c for c in implicit.values() if c.integrator.startswith("stand-in")]
    assert len(stand_ins) == len(benchmark.RTOLS) + len(benchmark.IMPLICIT_DTS)
    assert {"implicit-euler", "implicit-midpoint", "esdirk4"} <= {c.integrator for c in implicit.values()}
    explicit = {config.integrator for group, config in rows.values() if group == "pinstab explicit"}
    assert explicit == {"rk4", "dopri5", "dop853"}


def test_benchmark_ratios_name_the_acceptance_line(benchmark, implicit_stand_ins):
    """The ratios are the cheapest implicit pinstab run within 1e-6 rad over SciPy's cheapest implicit run and over
    pinstab's cheapest explicit one; "n/a" (None) where a side has none."""

    def row(group, cpu, error):
        return {"group": group, "cpu_s": cpu, "within": error <= benchmark.TOLERANCE}

    table = {
        "a": row("pinstab implicit", 0.2, 5e-7),
        "b": row("pinstab implicit", 0.1, 2e-6),  # cheaper, not within
        "c": row("scipy-radau", 1.0, 9e-7),
        "d": row("scipy-bdf", 0.8, 1e-7),
        "e": row("scipy-dop853", 0.1, 1e-7),  # explicit: not SciPy's implicit best
        "f": row("pinstab explicit", 4.0, 1e-8),
    }
    bests, acceptance = benchmark.ratios(table)
    assert bests["scipy implicit"] == "d" and bests["pinstab implicit"] == "a"
    assert acceptance["pinstab implicit / scipy implicit"]["value"] == pytest.approx(0.25)
    assert acceptance["pinstab implicit / pinstab explicit"]["value"] == pytest.approx(0.05)
    assert acceptance["pinstab implicit / scipy implicit"]["met"] is True
    del table["a"]
    assert benchmark.ratios(table)[1]["pinstab implicit / scipy implicit"]["value"] is None


def test_benchmark_measures_an_implicit_stand_in(benchmark, implicit_stand_ins, monkeypatch):
    """A short run of the whole benchmark: the stand-in implicit rows are measured like the others (RK4's step at
    5e-5 s reaches the tolerance over 0.02 s), so the acceptance ratios are figures, not n/a."""
    monkeypatch.setattr(benchmark, "ROUNDS", 1)
    monkeypatch.setattr(benchmark, "MUJOCO_IMPLICIT_DTS", (1e-4,))
    monkeypatch.setattr(benchmark, "MUJOCO_RK4_DTS", (1e-4,))
    _, table = benchmark.measure(0.02)
    _, acceptance = benchmark.ratios(table)
    assert table["pinstab stand-in-fixed dt=5e-05"]["within"]
    assert all(entry["value"] > 0 for entry in acceptance.values())
