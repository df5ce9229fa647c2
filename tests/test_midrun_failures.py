"""Failures once a run has started are results, not bad input: a servo the controls cannot realize after t = 0 s
stops the run with exit 5 and keeps its samples (at t = 0 s it is the scene's start, refused with exit 2 by ``check``
and ``run`` alike); a KKT solve that fails at a state the run reached is a divergence (exit 3). Found by the table
fuzzer on the lowest releases (tests/test_fuzz_tables.py::test_closures_servos_and_limits_refused_alike_or_kept)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import pinstab.solvers.proxsuite_ as proxsuite_backend
from pinstab import Trajectory
from pinstab.cli import main
from pinstab.errors import SolverError

ROBOTS = Path(__file__).resolve().parents[1] / "robots"


def homing(tmp_path: Path, old: str, new: str) -> Path:
    """robots/homing.toml with ``old`` replaced by ``new`` in its [initial] table."""
    text = (ROBOTS / "homing.toml").read_text(encoding="utf-8")
    assert old in text
    text = text.replace('urdf = "urdf/homing.urdf"', f'urdf = "{ROBOTS / "urdf" / "homing.urdf"}"')
    path = tmp_path / "homing.toml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_servo_beyond_its_controls_mid_run_stops_with_its_samples(tmp_path, capsys):
    """y1 = 1e6 m: the assembly puts m1 and m2 half-way (y = 5e5 m), the 8 N/m spring pulls m1 back with 4e6 N and
    at t = 0.0015 s the control y2 would need -1200 N, outside its URDF limit [-1000, 1000] N. ``check`` passes (the
    start is realizable: 0.24 N); ``run`` stops with exit 5, the run's figures and samples up to the last checked
    state kept, as a contact failure is."""
    scene = homing(tmp_path, "y1 = 0.4,", "y1 = 1000000.0,")
    code, _, err = cli(capsys, "check", str(scene), "--json")
    assert code == 0, err
    saved = tmp_path / "run.npz"
    code, out, err = cli(capsys, "run", str(scene), "--duration", "0.1", "--quiet", "--json", "--save", str(saved))
    assert code == 5 and "Traceback" not in err, err
    assert "servo 'homing-y', 'homing-z' cannot be realized at t = 0.0015 s within the control limits" in err
    assert "y2 = -1200 outside [-1000, 1000]" in err
    result = json.loads(out)
    assert result["stopped"]["reason"] == "servo failure" and result["stopped"]["error"] == "ServoInfeasibleError"
    kept = Trajectory.load(saved)
    assert kept.t[-1] < 0.0015 and np.all(np.diff(kept.t) > 0) and np.all(np.isfinite(kept.q))
    code, _, err = cli(capsys, "servo", str(scene), "--duration", "0.1", "--quiet")
    assert code == 5 and "Traceback" not in err, err


def test_servo_beyond_its_controls_at_the_start_is_refused_by_check_and_run(tmp_path, capsys):
    """x2' = 1e6 m/s: the controls would need y2 = 9.8e4 N at t = 0 s (the limit is 1000 N): ``check``, ``run`` and
    ``servo`` refuse it with exit 2, the message saying it is the scene's initial state."""
    scene = homing(tmp_path, "x2 = 0.8,", "x2 = 1000000.0,")
    for command in ("check", "run", "servo"):
        code, out, err = (
            cli(capsys, command, str(scene), "--duration", "0.1", "--quiet")[0:3]
            if command != "check"
            else cli(capsys, command, str(scene))
        )
        assert code == 2 and out == "", (command, err)
        assert "cannot be realized at t = 0 s (the scene's initial state) within the control limits" in err
        assert "y2 = 9.796e+04 outside [-1000, 1000]" in err


@pytest.fixture
def failing_from(monkeypatch):
    """ProxQP made to fail at every solve once one at or after the time given [s] has been asked for (a closure that
    becomes inconsistent mid-run, simulated: the last good state fails too); returns a setter."""
    original = proxsuite_backend.ProxsuiteSolver.solve

    def set_from(t_fail: float) -> None:
        failed = []

        def solve(self, problem):
            if problem.t >= t_fail or failed:
                failed.append(problem.t)
                raise SolverError(f"proxsuite: ProxQP did not solve the constrained dynamics at t = {problem.t:.6g} s")
            return original(self, problem)

        monkeypatch.setattr(proxsuite_backend.ProxsuiteSolver, "solve", solve)

    return set_from


def test_kkt_solve_failing_mid_run_is_a_divergence(tmp_path, capsys, failing_from):
    """fourbar with the proxsuite backend failing from t = 0.2 s: exit 3 (it was 2, bad input), the samples up to
    the last good state saved, and the message naming the failed solve; failing from t = 0 s it stays bad input."""
    saved = tmp_path / "run.npz"
    failing_from(0.2)
    argv = ["run", str(ROBOTS / "fourbar.toml"), "--solver", "proxsuite", "--duration", "0.3", "--quiet"]
    code, _, err = cli(capsys, *argv, "--save", str(saved))
    assert code == 3 and "Traceback" not in err, err
    assert "the KKT solve failed at a state the run reached" in err
    kept = Trajectory.load(saved)
    assert 0.1 <= kept.t[-1] < 0.2 and np.all(np.isfinite(kept.q))
    failing_from(0.0)
    code, _, err = cli(capsys, *argv)
    assert code == 2 and "ProxQP did not solve" in err, err
