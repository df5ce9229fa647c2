"""What a run's wall time covers: simulate()'s whole call split into set-up, stepping and post-processing (kept with
the trajectory), and the command line's whole process, its start read from /proc, split as well."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pinstab import Trajectory, simulate
from pinstab.cli import main
from pinstab.runinfo import RunInfo

ENV = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}
PARTS = ("setup_s", "stepping_s", "post_s")
COMMAND_PARTS = ("startup_s", "setup_s", "stepping_s", "post_s", "output_s")


def test_simulate_wall_time_is_the_call_split_in_three(tmp_path):
    """The trajectory's wall time is the sum of its set-up, stepping and post-processing, each positive, and lies
    within the call's time measured around it; the split is saved with the run and loaded back; a file saved without
    it (an older run) loads with none."""
    began = time.perf_counter()
    trajectory = simulate("fourbar", duration=0.2)
    outside = time.perf_counter() - began
    timings = trajectory.info.timings
    assert set(timings) == set(PARTS) and all(timings[part] > 0 for part in PARTS)
    assert trajectory.wall_time == sum(timings.values())
    assert timings["stepping_s"] < trajectory.wall_time <= outside
    assert trajectory.summary()["wall_s"] == trajectory.wall_time
    assert trajectory.summary()["timings"] == timings
    path = trajectory.save(tmp_path / "run.npz")
    assert Trajectory.load(path).info.timings == timings
    older = {key: value for key, value in trajectory.info.to_dict().items() if key != "timings"}
    assert RunInfo.from_dict(older).timings == {}


def test_command_wall_time_counts_from_the_process_start_and_its_parts_add_up(capsys):
    """``pinstab run --json``: ``wall_s`` covers at least the command's own time measured around it, and the five
    parts (start-up, set-up, stepping, post-processing, output) are non-negative and add up to it (to rounding)."""
    began = time.perf_counter()
    assert main(["run", "fourbar", "--duration", "0.2", "--json"]) == 0
    around = time.perf_counter() - began
    result = json.loads(capsys.readouterr().out)
    timings = result["timings"]
    assert set(timings) == set(COMMAND_PARTS) and min(timings.values()) >= 0
    assert timings["stepping_s"] > 0
    assert sum(timings.values()) == pytest.approx(result["wall_s"], rel=1e-12)
    assert around < result["wall_s"]  # this test's process started before the command


def test_process_start_is_read_to_the_clock_tick():
    """In a fresh process that sleeps 0.5 s before importing pinstab, the time since its start is at least the
    sleep (less the kernel's clock tick, 10 ms) and less than the sleep plus start-up and imports (5 s)."""
    child = (
        "import time; time.sleep(0.5)\n"
        "from pinstab.cli.clock import process_started\n"
        "print(time.perf_counter() - process_started())\n"
    )
    if not Path("/proc/self/stat").exists():
        pytest.skip("no /proc: the start is when pinstab.cli.clock was imported")
    output = subprocess.run([sys.executable, "-c", child], env=ENV, capture_output=True, text=True, check=True)
    since = float(output.stdout)
    assert 0.49 <= since < 5.5, since
