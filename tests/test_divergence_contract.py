"""One divergence contract (issue 13, item 6): every blow-up exits 3 whatever the solver, with the figures up
to the last finite state and ``--save`` writing the partial trajectory; Ctrl-C exits 130 and SIGTERM 143 (partial save);
a closed stdout ends quietly; no temporary file survives an interrupted save."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from conftest import interruptible
from pinstab import DivergenceError, SolverError, Trajectory, simulate
from pinstab import scene as scene_module
from pinstab.cli import main
from pinstab.integration import stepping

SOLVERS = ("dense", "proxsuite", "pinocchio")
# projection at dt = 0.5 s: one step passes, the second explodes (energy 6.3 J -> 1.4e3 J after the first);
# ProxQP fails inside that step, the others' projection fails after it (ProxQP used to exit 2 without JSON)
EXPLODING = "run fourbar --method projection --dt 0.5 --duration 20 --quiet --json"
# undamped and too stiff for the step: the drift passes 1 at step 224, in the third chunk of checks
STIFF = "run fourbar --kp 3.6e4 --kd 0 --integrator semi-implicit-euler --dt 1e-2 --duration 5 --quiet --json"
STATE_KEYS = {"t", "q", "v"}
DIVERGED_KEYS = {"diverged", "diverged_at", "last_finite_state", "error", "final_position_drift", "energy_end"}


def run_cli(capsys, argv: str, *extra: str) -> tuple[int, str, str]:
    code = main([*argv.split(), *extra])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("argv", [EXPLODING, STIFF])
def test_every_solver_exits_3_with_the_same_json_keys(capsys, argv):
    payloads = {}
    for solver in SOLVERS:
        code, out, err = run_cli(capsys, argv, "--solver", solver)
        assert code == 3, (solver, err)
        assert "Traceback" not in err and "diverged at t = " in err
        payloads[solver] = json.loads(out)
    keys = {solver: set(payload) for solver, payload in payloads.items()}
    assert keys["dense"] == keys["proxsuite"] == keys["pinocchio"]
    assert DIVERGED_KEYS <= keys["dense"]
    for solver, payload in payloads.items():
        assert payload["diverged"] is True and payload["solver"] == solver
        assert set(payload["last_finite_state"]) == STATE_KEYS
        assert len(payload["last_finite_state"]["q"]) == 3 and len(payload["last_finite_state"]["v"]) == 3
        # the failed step is the one after the last finite state
        assert payload["diverged_at"] == pytest.approx(payload["last_finite_state"]["t"] + payload["dt"], abs=1e-12)
        assert payload["t_end"] == payload["last_finite_state"]["t"]


def test_a_solve_failing_inside_a_step_is_a_divergence_not_a_solver_error():
    """ProxQP fails at the stage t = 0.75 s of step 2 (it solves the state at 0.5 s): a divergence at t = 1 s
    (ProxQP for every solve: the backend's Cholesky solve of independent rows does not fail there)."""
    with pytest.raises(DivergenceError, match="KKT solve failed") as info:
        simulate(
            "fourbar", method="projection", dt=0.5, duration=20.0, solver="proxsuite", solver_options={"direct": False}
        )
    error = info.value
    assert (error.diverged_at, error.time) == (1.0, 0.5)
    # the trajectory ends with the failed step (its state never reached: NaN), the finite one before it
    np.testing.assert_array_equal(error.trajectory.t, [0.0, 0.5, 1.0])
    assert np.isnan(error.trajectory.q[-1]).all() and error.trajectory.steps == 2
    np.testing.assert_array_equal(error.finite_trajectory.t, [0.0, 0.5])
    np.testing.assert_array_equal(error.finite_trajectory.q[-1], error.q)
    assert error.finite_trajectory.steps == 1 and error.finite_trajectory.info.t_end == 0.5


def test_a_solver_refusing_the_initial_state_is_still_bad_input(capsys):
    """The dense solver's rank loss on fivebar fails on the assembled start itself: exit 2, not a divergence."""
    with pytest.raises(SolverError, match="lost rank"):
        simulate("fivebar", solver="dense", dt=1e-3, duration=0.01)
    code, out, err = run_cli(capsys, "run fivebar --solver dense --duration 0.01 --json --quiet")
    assert code == 2 and out == "" and "lost rank" in err


@pytest.mark.parametrize(("record_every", "samples"), [(1, 224), (10, 24)])
def test_json_figures_and_save_end_at_the_last_finite_state(capsys, tmp_path, record_every, samples):
    path = tmp_path / "partial.npz"
    code, out, err = run_cli(capsys, STIFF, "--save", str(path), "--record-every", str(record_every))
    assert code == 3, err
    payload = json.loads(out)
    assert "(step 224)" in payload["error"] and payload["saved"] == str(path)
    assert payload["diverged_at"] == pytest.approx(2.24) and payload["last_finite_state"]["t"] == pytest.approx(2.23)
    partial = Trajectory.load(path)
    assert len(partial.t) == samples and partial.steps == payload["steps"] == 223
    assert partial.t[-1] == payload["last_finite_state"]["t"] == payload["t_end"]
    assert payload["diverged_at"] - partial.t[-1] == pytest.approx(1e-2)
    np.testing.assert_array_equal(partial.q[-1], payload["last_finite_state"]["q"])
    np.testing.assert_array_equal(partial.v[-1], payload["last_finite_state"]["v"])
    assert np.isfinite(partial.q).all() and np.isfinite(partial.v).all() and np.isfinite(partial.energy).all()
    assert payload["final_position_drift"] == partial.position_drift[-1]
    assert payload["final_velocity_drift"] == partial.velocity_drift[-1]
    assert payload["energy_end"] == partial.energy[-1]
    assert payload["max_position_drift"] == partial.position_drift.max() <= 1.0  # below the drift limit
    assert payload["max_velocity_drift"] == partial.velocity_drift.max()


def interrupt_at_check(monkeypatch, calls: int) -> None:
    """Ctrl-C at the ``calls``-th check of the stepping loop (the check after steps 100 (calls - 1) + 1 ..)."""
    original = stepping.StepLoop.check
    seen = []

    def check(self, q, v, k):
        seen.append(k)
        if len(seen) == calls:
            raise KeyboardInterrupt
        return original(self, q, v, k)

    monkeypatch.setattr(stepping.StepLoop, "check", check)


def test_ctrl_c_exits_130_with_one_line_and_the_partial_save(capsys, monkeypatch, tmp_path):
    interrupt_at_check(monkeypatch, 3)  # steps 1..200 checked, interrupted in the chunk 201..300
    path = tmp_path / "partial.npz"
    code, out, err = run_cli(capsys, "run fourbar --duration 1 --quiet --save", str(path))
    assert code == 130 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("pinstab run: interrupted at t = 0.2 s (step 200)") and str(path) in err
    partial = Trajectory.load(path)
    assert len(partial.t) == 201 and partial.t[-1] == pytest.approx(0.2) and partial.steps == 200
    assert np.isfinite(partial.q).all() and partial.position_drift.max() < 1e-6


@pytest.mark.parametrize("command", ["run fourbar", "record fourbar -o {tmp}/r.html"])
def test_ctrl_c_without_save_exits_130(capsys, monkeypatch, tmp_path, command):
    interrupt_at_check(monkeypatch, 1)
    code, out, err = run_cli(capsys, command.format(tmp=tmp_path), "--quiet")
    assert code == 130 and out == "" and "Traceback" not in err
    assert err == f"pinstab {command.split()[0]}: interrupted at t = 0 s (step 0)\n"
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_before_the_run_exits_130(capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(scene_module, "load_scene", interrupted)
    code, out, err = run_cli(capsys, "run fourbar --quiet")
    assert (code, out, err) == (130, "", "pinstab run: interrupted\n")


def test_an_interrupted_save_leaves_no_temporary_file_and_the_old_file_intact(capsys, monkeypatch, tmp_path):
    path = tmp_path / "run.npz"
    assert main(["run", "fourbar", "--duration", "0.01", "--quiet", "--save", str(path)]) == 0
    before = path.read_bytes()
    written = []

    def savez_then_ctrl_c(file, **arrays):
        written.append(file)
        with open(file, "wb") as handle:
            handle.write(b"half a file")
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savez_compressed", savez_then_ctrl_c)
    code, _, err = run_cli(capsys, "run fourbar --duration 0.02 --quiet --save", str(path))
    assert code == 130 and "Traceback" not in err
    assert len(written) == 1 and os.path.dirname(written[0]) == str(tmp_path)  # the temp file was in the folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.npz"]
    assert path.read_bytes() == before


def cli(*argv: str) -> list[str]:
    return [sys.executable, "-m", "pinstab.cli", *argv]


def test_a_closed_stdout_ends_quietly():
    """The reader is gone before pinstab prints: BrokenPipeError is caught, the exit code is kept."""
    read, write = os.pipe()
    os.close(read)
    try:
        completed = subprocess.run(
            cli("run", "fourbar", "--duration", "0.01", "--json", "--quiet"), stdout=write, stderr=subprocess.PIPE
        )
    finally:
        os.close(write)
    assert completed.returncode == 0
    assert completed.stderr == b""


def test_json_piped_into_head_has_no_traceback():
    command = " ".join(cli("run", "fourbar", "--json", "--quiet")) + " | head -c 10"
    completed = subprocess.run(["bash", "-c", f"set -o pipefail; {command}"], capture_output=True, text=True)
    assert completed.stdout == '{"scene": '
    assert completed.returncode == 0 and "Traceback" not in completed.stderr and "Error" not in completed.stderr


@pytest.mark.parametrize(
    ("signum", "code", "said"), [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "stopped by SIGTERM")]
)
def test_a_real_signal_mid_run_saves_the_partial_trajectory_and_no_temporary_file(tmp_path, signum, code, said):
    """A real Ctrl-C or ``kill`` (not a monkeypatched one) 5 s into a run of 1e7 steps that takes longer (the
    compiled loop takes the four-bar to about t = 470 s in those 5 s: a run of 1e6 steps would end soon after)."""
    path = tmp_path / "partial.npz"
    argv = ("run", "fourbar", "--duration", "10000", "--record-every", "100", "--quiet", "--save", str(path))
    process = subprocess.Popen(
        cli(*argv), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=interruptible
    )
    try:
        process.wait(timeout=5.0)
    except subprocess.TimeoutExpired:
        process.send_signal(signum)
    out, err = process.communicate(timeout=60)
    assert process.returncode == code and out == "" and "Traceback" not in err
    assert err.startswith(f"pinstab run: {said} at t = ") and err.count("\n") == 1
    partial = Trajectory.load(path)
    assert 0 < partial.t[-1] < 10000 and np.isfinite(partial.q).all()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["partial.npz"]
