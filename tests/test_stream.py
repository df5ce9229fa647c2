"""Runs streamed to HDF5 (``simulate(stream=...)``, ``pinstab run --stream``): the same samples and series as a run
kept in memory, memory that does not grow with the duration, a file readable while the run proceeds and after
a kill."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ROBOTS, fourbar_dict
from pinstab.cli import main
from pinstab.errors import CutShortWarning, PinstabError
from pinstab.scene import scene_from_dict
from pinstab.simulate import simulate
from pinstab.stream import BLOCK, read_stream
from pinstab.trajectory import StreamedTrajectory, Trajectory

h5py = pytest.importorskip("h5py")

SERIES = ("t", "q", "v", "correction_iterations", "multipliers", "position_drift", "velocity_drift", "energy")
CHILD = (  # a run in a fresh process; prints its peak resident set size [KiB]
    "import resource, sys\n"
    "from pinstab.cli import main\n"
    "code = main(sys.argv[1:])\n"
    "print('PEAK_KIB', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, 'EXIT', code)\n"
)
ENV = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}


@pytest.mark.parametrize("every", [1, 3])
def test_streamed_run_is_the_run_kept_in_memory(tmp_path, every):
    """Over more than one block (and a last sample off the K grid with every = 3) the file holds exactly, to 0,
    the samples and derived series of the same run kept in memory, and the same summary figures."""
    duration = 2.5 * BLOCK * every / 1000 + 0.0015
    kept = simulate("fourbar", duration=duration, record_every=every)
    streamed = simulate("fourbar", duration=duration, record_every=every, stream=tmp_path / "run.h5")
    assert isinstance(streamed, StreamedTrajectory)
    loaded = Trajectory.load(tmp_path / "run.h5")
    assert len(kept.t) > 2 * BLOCK
    for name in (*SERIES, "spectral_radius"):
        assert np.array_equal(getattr(kept, name), getattr(loaded, name), equal_nan=True), name
    assert loaded.info.to_dict() == {
        **kept.info.to_dict(),
        "solver_statistics": loaded.info.to_dict()["solver_statistics"],
        "timings": loaded.info.to_dict()["timings"],  # wall-clock times: the two runs' own
    }
    assert loaded.info.steps == kept.info.steps and loaded.info.t_end == kept.info.t_end
    assert loaded.wall_time == streamed.wall_time == sum(streamed.info.timings.values())
    figures, reference = streamed.summary(), kept.summary()
    for name in ("max_position_drift", "max_velocity_drift", "final_position_drift", "energy_start", "energy_end"):
        assert figures[name] == reference[name], name
    # the block-wise least-squares fit against numpy's polyfit over the whole second half
    assert figures["drift_growth_exponent"] == pytest.approx(reference["drift_growth_exponent"], rel=1e-9)


def test_a_run_the_joint_limits_send_to_the_event_path(tmp_path):
    """A four-bar whose crank is limited to 1.5 rad: the held run leaves the limit, the run is made again by the
    event path (dop853, dense output), streamed to the same file: the samples and info of the run kept in memory."""
    data = fourbar_dict()
    urdf = (ROBOTS / "urdf" / "fourbar.urdf").read_text()
    data["robot"] = {"urdf_text": urdf.replace("<limit effort", '<limit lower="-10" upper="1.5" effort', 1)}
    scene = scene_from_dict(data, base_dir=ROBOTS)
    kept = simulate(scene, duration=1.0)
    simulate(scene, duration=1.0, stream=tmp_path / "run.h5")
    loaded = Trajectory.load(tmp_path / "run.h5")
    assert kept.info.path == loaded.info.path == "contact-events"
    assert loaded.info.path_reason == kept.info.path_reason
    assert loaded.info.limits_active_s == kept.info.limits_active_s and "crank upper" in kept.info.limits_active_s
    for name in SERIES:
        assert np.array_equal(getattr(kept, name), getattr(loaded, name), equal_nan=True), name


def test_file_layout_is_plain_and_documented(tmp_path):
    """Plain datasets with units, the run info as attributes, readable by h5py alone."""
    simulate("fourbar", duration=0.2, stream=tmp_path / "run.h5")
    with h5py.File(tmp_path / "run.h5", "r") as file:
        assert file["q"].shape == (201, 3) and file["multipliers"].shape == (201, 2)
        assert file["t"].attrs["units"] == "s" and file["energy"].attrs["units"] == "J"
        assert file.attrs["scene"] == "fourbar" and file.attrs["method"] == "baumgarte" and file.attrs["complete"]
        assert json.loads(file.attrs["info"])["steps"] == 200
        assert np.array_equal(file["step"][()], np.arange(201))


def peak_kib(*argv: str) -> int:
    """Peak RSS [KiB] of ``pinstab ARGV`` in a fresh process."""
    done = subprocess.run([sys.executable, "-c", CHILD, *argv], capture_output=True, text=True, env=ENV, check=True)
    fields = done.stdout.split("PEAK_KIB")[-1].split()
    assert fields[2] == "0", done.stderr
    return int(fields[0])


def test_memory_does_not_grow_with_the_duration(tmp_path):
    """5 s and 50 s streamed (every step kept) peak within 5 MiB of each other; kept in memory the 45 000 more
    samples and their series cost tens of MiB (about 1.2 KiB a sample measured on this four-bar)."""
    short = peak_kib("run", "fourbar", "--duration", "5", "--quiet", "--stream", str(tmp_path / "a.h5"))
    long = peak_kib("run", "fourbar", "--duration", "50", "--quiet", "--stream", str(tmp_path / "b.h5"))
    assert abs(long - short) < 5 * 1024, (short, long)


@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM])
def test_a_killed_run_leaves_its_samples(tmp_path, signum):
    """Read while the run proceeds (SWMR), then killed: the file holds the blocks flushed so far, the samples of
    the same run kept in memory; SIGTERM ends it cleanly (exit 143, the final info written, the file named)."""
    path = tmp_path / "run.h5"
    argv = [
        sys.executable,
        "-m",
        "pinstab.cli",
        "run",
        "fourbar",
        "--duration",
        "10000",  # longer than the polling below (1000 s of it ran to its end, in 10 s of wall time, once in CI)
        "--quiet",
        "--stream",
        str(path),
    ]
    process = subprocess.Popen(argv, env=ENV, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            time.sleep(0.3)
            if path.exists():
                try:
                    if len(read_stream(path)[0]["t"]) >= 2 * BLOCK:
                        break
                except PinstabError:  # created, not yet in SWMR mode
                    continue
        process.send_signal(signum)
        _, stderr = process.communicate(timeout=30)
    finally:
        process.kill()
    with pytest.warns(CutShortWarning, match="the run was cut short"):
        loaded = Trajectory.load(path)
    n = len(loaded.t)
    assert n >= 2 * BLOCK
    m = 2 * BLOCK  # the samples compared: another run of their duration, equal to rounding (1.4e-14 measured)
    kept = simulate("fourbar", duration=(m - 1) / 1000)
    assert np.abs(loaded.q[:m] - kept.q).max() < 1e-12 and np.abs(loaded.v[:m] - kept.v).max() < 1e-10
    assert loaded.info.cut_short["t"] == loaded.t[-1] and np.all(np.isnan(loaded.energy))
    if signum == signal.SIGTERM:  # the samples to the last checked state written, and the final info
        assert process.returncode == 143 and str(path) in stderr
        assert loaded.info.steps == n - 1
    else:  # the rows flushed before the kill
        assert process.returncode == -signal.SIGKILL


def test_cli_plot_and_record_read_a_streamed_run(tmp_path, capsys):
    path, chart, page = tmp_path / "run.h5", tmp_path / "run.png", tmp_path / "run.html"
    assert main(["run", "fourbar", "--duration", "0.5", "--quiet", "--json", "--stream", str(path)]) == 0
    assert json.loads(capsys.readouterr().out)["stream"] == str(path)
    assert main(["plot", str(path), "-o", str(chart)]) == 0 and chart.stat().st_size > 0
    capsys.readouterr()
    assert main(["record", "fourbar", "--from", str(path), "-o", str(page), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["frames"] == 16  # 0.5 s at 30 fps and the first frame
    assert main(["record", "nfourbar", "--from", str(path), "-o", str(page)]) == 2
    assert "3 coordinates" in capsys.readouterr().err
    assert main(["run", "fourbar", "--stream", str(path), "--save", str(tmp_path / "x.npz")]) == 2
    assert "--save: --stream keeps the run on disk" in capsys.readouterr().err


def test_missing_h5py_is_named(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "h5py", None)
    with pytest.raises(PinstabError, match=r"pinstab\[stream\]"):
        simulate("fourbar", duration=0.1, stream=tmp_path / "run.h5")
    assert not (tmp_path / "run.h5").exists()


def test_not_a_run_file(tmp_path):
    with h5py.File(tmp_path / "other.h5", "w") as file:
        file["x"] = np.zeros(3)
    with pytest.raises(PinstabError, match="not a pinstab run file"):
        Trajectory.load(tmp_path / "other.h5")
    (tmp_path / "text.h5").write_text("hello")
    with pytest.raises(PinstabError, match="not a readable HDF5 run file"):
        Trajectory.load(tmp_path / "text.h5")


def info_writes(monkeypatch) -> list[dict]:
    """The run info each write of a stream's final info writes (``pinstab.stream.rewrite_info``, counted)."""
    import pinstab.trajectory

    writes: list[dict] = []
    write = pinstab.trajectory.rewrite_info

    def counted(path, info, wall_time, complete):
        writes.append({"info": info.to_dict(), "wall_time": wall_time, "complete": complete})
        write(path, info, wall_time, complete)

    monkeypatch.setattr(pinstab.trajectory, "rewrite_info", counted)
    return writes


def interrupt_at_check(monkeypatch, records: type, check: int) -> None:
    """Ctrl-C (a KeyboardInterrupt) at the loop's ``check``-th check of its samples (``records.checked``)."""
    calls = []
    checked = records.checked

    def interrupted(self, k):
        calls.append(k)
        if len(calls) == check:
            raise KeyboardInterrupt
        checked(self, k)

    monkeypatch.setattr(records, "checked", interrupted)


def test_a_streamed_runs_info_is_written_once(tmp_path, monkeypatch):
    """The final info of a stream is written once, whatever ends the run: once at its end (complete, with the
    wall time the run reports), once when it is interrupted (with ``cut_short``), once when it diverges."""
    from pinstab.errors import DivergenceError
    from pinstab.integration import StreamedRecords
    from pinstab.simulate import Interrupted

    writes = info_writes(monkeypatch)
    run = simulate("fourbar", duration=0.5, stream=tmp_path / "run.h5")
    assert len(writes) == 1 and writes[0]["complete"] and writes[0]["wall_time"] == run.wall_time
    assert writes[0]["info"]["steps"] == 500 and writes[0]["info"]["timings"] == run.info.timings

    writes.clear()
    with pytest.raises(DivergenceError):
        simulate("fourbar", method="none", drift_limit=1e-12, duration=1, stream=tmp_path / "diverged.h5")
    assert len(writes) == 1 and writes[0]["complete"]

    writes.clear()
    interrupt_at_check(monkeypatch, StreamedRecords, 3)  # after 2 checks of 100 steps each
    with pytest.raises(Interrupted) as stopped:
        simulate("fourbar", duration=1.0, stream=tmp_path / "cut.h5")
    assert len(writes) == 1 and not writes[0]["complete"]
    cut_short = {"t": pytest.approx(0.2, abs=1e-12), "step": 200, "cause": "interrupted"}
    assert writes[0]["info"]["cut_short"] == cut_short == stopped.value.trajectory.info.cut_short
    with pytest.warns(CutShortWarning, match=r"cut.h5: the run was cut short at t = 0.2 s \(step 200\): interrupted"):
        loaded = Trajectory.load(tmp_path / "cut.h5")
    assert loaded.info.cut_short == cut_short and len(loaded.t) == 201
