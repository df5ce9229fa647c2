"""Run files against hostile conditions (issue 34, item 3): ``--stream`` writes like ``--save`` (a temporary file
renamed onto the target: a link there replaced, never followed); a stream cut short by SIGINT, SIGTERM or
``kill -9`` is read by ``pinstab plot``, ``pinstab record --from`` and ``Trajectory.load``, which say so; a
truncated or damaged HDF5 file, a damaged NPZ and a CSV given as a run are named errors (exit 2, the file and what
is wrong), in bounded time."""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from test_stream import interrupt_at_check

from conftest import interruptible
from pinstab.cli import main
from pinstab.errors import CutShortWarning, PinstabError, PinstabWarning
from pinstab.runinfo import RunInfo
from pinstab.simulate import simulate
from pinstab.stream import BLOCK, GLOBAL_HEAP, StreamWriter, read_stream
from pinstab.trajectory import Trajectory

h5py = pytest.importorskip("h5py")

ENV = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}


def plot(path: Path, capsys) -> tuple[int, str]:
    """(exit code, stderr) of ``pinstab plot PATH -o chart.png`` beside it."""
    capsys.readouterr()
    code = main(["plot", str(path), "-o", str(path.parent / "chart.png")])
    return code, capsys.readouterr().err


def record_from(path: Path, capsys) -> tuple[int, str]:
    """(exit code, stderr) of ``pinstab record fourbar --from PATH -o page.html`` (2 frames a second)."""
    capsys.readouterr()
    code = main(["record", "fourbar", "--from", str(path), "-o", str(path.parent / "page.html"), "--fps", "2"])
    return code, capsys.readouterr().err


# --- a stream written like --save -----------------------------------------------------------------------------


def test_a_stream_replaces_a_link_and_never_follows_it(tmp_path, capsys):
    """The issue's example: ``--stream run.h5`` where run.h5 is a symbolic link to another file: that file keeps its
    bytes, run.h5 becomes the run's own file, and no temporary file is left."""
    kept = tmp_path / "precious.h5"
    kept.write_bytes(b"not to be overwritten")
    (tmp_path / "run.h5").symlink_to(kept)
    dangling = tmp_path / "dangling.h5"
    dangling.symlink_to(tmp_path / "nowhere.h5")
    for link in (tmp_path / "run.h5", dangling):
        assert main(["run", "fourbar", "--duration", "0.05", "--quiet", "--stream", str(link)]) == 0
        assert not link.is_symlink() and len(Trajectory.load(link).t) == 51
    assert kept.read_bytes() == b"not to be overwritten" and not (tmp_path / "nowhere.h5").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dangling.h5", "precious.h5", "run.h5"]
    assert oct((tmp_path / "run.h5").stat().st_mode & 0o777) == oct(0o666 & ~current_umask())


def current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_the_target_is_the_run_file_from_its_first_row_and_an_error_before_leaves_the_old_one(tmp_path):
    """The stream's file is renamed onto the target with its first rows: before, it is a temporary file beside the
    target (SWMR, no rows yet), which a writer closed without rows removes, as one that fails (here: h5py refusing
    the layout): the old file stays, no temporary is left (tests/test_stream_start.py: the first rows)."""
    path = tmp_path / "run.h5"
    path.write_bytes(b"the previous run")
    info = RunInfo("fourbar", "baumgarte", "rk4", "pinocchio", 1e-3)
    with pytest.raises(ValueError):
        StreamWriter(path, info, nq=-1, nv=3, rows=2)  # a negative width: h5py refuses the dataset
    assert path.read_bytes() == b"the previous run" and [p.name for p in tmp_path.iterdir()] == ["run.h5"]
    writer = StreamWriter(path, info, nq=3, nv=3, rows=2)
    try:
        assert path.read_bytes() == b"the previous run" and len(list(tmp_path.iterdir())) == 2
        shutil.copyfile(writer.temp, tmp_path / "now.h5")  # as a reader in another process sees it
    finally:
        writer.close()
    assert path.read_bytes() == b"the previous run"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["now.h5", "run.h5"]
    arrays, read_info, _, complete = read_stream(tmp_path / "now.h5")
    assert len(arrays["t"]) == 0 and not complete and read_info.scene == "fourbar"
    with pytest.raises(
        PinstabError,
        match=r"holds no sample yet \(its rows are written every 4096 samples or 1 s: a run's file before its first",
    ):
        Trajectory.load(tmp_path / "now.h5")


# --- a stream cut short ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL])
def test_a_stream_cut_short_is_read_by_plot_record_and_load(tmp_path, capsys, signum):
    """A real run streamed, stopped by a signal once its file holds rows: ``Trajectory.load`` reads every row written
    (the same states as the run kept in memory) and warns that it was cut short at its last time; ``pinstab plot``
    and ``pinstab record --from`` exit 0 and say so (they ended in ``KeyError: 'error'``)."""
    path = tmp_path / "run.h5"
    argv = [
        sys.executable,
        "-m",
        "pinstab.cli",
        "run",
        "fourbar",
        "--duration",
        "1000",
        "--quiet",
        "--stream",
        str(path),
    ]
    process = subprocess.Popen(argv, env=ENV, stderr=subprocess.PIPE, text=True, preexec_fn=interruptible)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not rows_written(path):
            time.sleep(0.05)
        process.send_signal(signum)
        _, stderr = process.communicate(timeout=60)
    finally:
        process.kill()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]  # no temporary file left, even by kill -9
    with pytest.warns(CutShortWarning, match=r"run.h5: the run was cut short at t = [0-9.]+ s \(step [0-9]+\)"):
        loaded = Trajectory.load(path)
    n, t_end = len(loaded.t), float(loaded.t[-1])
    kept = simulate("fourbar", duration=(n - 1) / 1000)
    assert np.abs(loaded.q - kept.q).max() < 1e-12 and np.isnan(loaded.energy).all()
    assert loaded.info.t_end == t_end and loaded.info.steps == n - 1
    if signum == signal.SIGKILL:  # the rows flushed before the kill; the info is the run's start's
        assert process.returncode == -signal.SIGKILL and n >= BLOCK
        assert loaded.info.cut_short == {"t": t_end, "step": n - 1, "cause": "killed"}
    else:  # the samples to the last checked state and the final info written
        assert process.returncode == 128 + signum and str(path) in stderr
        assert loaded.info.cut_short == {"t": t_end, "step": n - 1, "cause": "interrupted"}
    said = f"cut short at t = {t_end:.9g} s"
    code, err = plot(path, capsys)
    assert code == 0 and said in err and "Traceback" not in err
    code, err = record_from(path, capsys)
    assert code == 0 and said in err and "Traceback" not in err
    assert (tmp_path / "page.html").stat().st_size > 0


def rows_written(path: Path) -> bool:
    """Whether the stream ``path`` exists and holds at least one block of rows."""
    try:
        return len(read_stream(path)[0]["t"]) >= BLOCK
    except (PinstabError, FileNotFoundError):
        return False


def test_a_saved_copy_of_a_stream_cut_short_keeps_saying_so(tmp_path):
    """``info.cut_short`` travels with the run: a loaded stream cut short saved as NPZ loads cut short, and says so."""
    path = killed_stream(tmp_path)
    with pytest.warns(CutShortWarning):
        trajectory = Trajectory.load(path)
    trajectory.save(tmp_path / "copy.npz")
    with pytest.warns(CutShortWarning, match=r"copy.npz: the run was cut short at t = 4.095 s \(step 4095\): killed"):
        copy = Trajectory.load(tmp_path / "copy.npz")
    assert copy.info.cut_short == {"t": 0.001 * BLOCK - 0.001, "step": BLOCK - 1, "cause": "killed"}


def killed_stream(folder: Path) -> Path:
    """A stream as ``kill -9`` leaves it: a block of the four-bar's rows flushed, the file never closed (its bytes
    copied while its writer holds it open)."""
    run = simulate("fourbar", duration=0.001 * (BLOCK - 1))
    path, copy = folder / "live.h5", folder / "killed.h5"
    writer = StreamWriter(path, run.info, nq=3, nv=3, rows=2)
    try:
        steps = np.arange(BLOCK)
        writer.write(0, run.t, steps, run.q, run.v, np.zeros(BLOCK, dtype=int))
        shutil.copyfile(path, copy)
    finally:
        writer.close()
    path.unlink()
    return copy


def test_a_stream_killed_before_its_first_block_keeps_its_rows_but_the_last_seconds(tmp_path):
    """Rows are flushed every FLUSH_PERIOD (1 s) of wall time as well as every block: the four-bar keeping a sample
    every 1000 steps fills a block in about half a minute (140 samples a second measured), yet a reader sees its rows
    grow second by second, and kill -9 leaves every row the reader saw (the samples of the same run kept in memory);
    before, the file held no row until its first block."""
    path = tmp_path / "run.h5"
    argv = [sys.executable, "-m", "pinstab.cli", "run", "fourbar", "--duration", "100000", "--record-every", "1000",
            "--quiet", "--stream", str(path)]  # fmt: skip
    process = subprocess.Popen(argv, env=ENV, stderr=subprocess.PIPE, text=True)
    seen: list[tuple[float, int]] = []  # (wall time [s], rows) each time the reader saw the rows grow
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and len(seen) < 3:
            rows = row_count(path)
            if rows and (not seen or rows > seen[-1][1]):
                seen.append((time.monotonic(), rows))
            time.sleep(0.05)
        process.send_signal(signal.SIGKILL)
        process.communicate(timeout=30)
    finally:
        process.kill()
    assert len(seen) == 3 and seen[-1][1] < BLOCK, seen  # three flushes before the first block
    assert np.diff([when for when, _ in seen]).max() < 2.0, seen  # a second apart (a reader polling, a busy machine)
    with pytest.warns(CutShortWarning, match="killed"):
        loaded = Trajectory.load(path)
    assert seen[-1][1] <= len(loaded.t) < BLOCK
    kept = simulate("fourbar", duration=9.0, record_every=1000)  # its first 10 samples, t = 0, 1, ..., 9 s
    assert np.array_equal(loaded.t[:10], kept.t) and np.abs(loaded.q[:10] - kept.q).max() < 1e-12


def row_count(path: Path) -> int:
    """The rows of the stream ``path`` a reader sees now (0 before the file exists or while it cannot be read)."""
    try:
        return len(read_stream(path)[0]["t"])
    except (PinstabError, FileNotFoundError):
        return 0


def test_a_run_interrupted_in_memory_is_cut_short(tmp_path, monkeypatch):
    """Ctrl-C during a run kept in memory, at its third check of 100 steps: the Interrupted's trajectory says it was
    cut short at its last checked state (step 200), and so does its saved file when loaded."""
    from pinstab.integration import Records
    from pinstab.simulate import Interrupted

    interrupt_at_check(monkeypatch, Records, 3)
    with pytest.raises(Interrupted) as stopped:
        simulate("fourbar", duration=1.0)
    trajectory = stopped.value.trajectory
    assert trajectory.info.cut_short == {"t": pytest.approx(0.2, abs=1e-12), "step": 200, "cause": "interrupted"}
    assert len(trajectory.t) == 201 and trajectory.info.t_end == trajectory.t[-1]
    trajectory.save(tmp_path / "run.npz")
    with pytest.warns(CutShortWarning, match=r"run.npz: the run was cut short at t = 0.2 s \(step 200\): interrupted"):
        assert Trajectory.load(tmp_path / "run.npz").info.cut_short == trajectory.info.cut_short


def test_a_run_stopped_by_sigterm_with_save_is_saved_cut_short(tmp_path, capsys):
    """``pinstab run --save`` stopped by SIGTERM once stepping (its progress bar shown): exit 143, the partial run
    saved, and loaded (and plotted) it says it was cut short at its last time (it loaded as a finished run)."""
    path = tmp_path / "run.npz"
    argv = [sys.executable, "-m", "pinstab.cli", "run", "fourbar", "--duration", "10000", "--record-every", "100",
            "--save", str(path)]  # fmt: skip
    process = subprocess.Popen(argv, env=ENV, stderr=subprocess.PIPE)
    try:
        shown = read_until(process, b"fourbar:", timeout=60)  # the bar appears after 2 s of stepping
        process.send_signal(signal.SIGTERM)
        _, rest = process.communicate(timeout=60)
    finally:
        process.kill()
    stderr = (shown + rest).decode()
    assert process.returncode == 143 and f"the partial trajectory is saved to {path}" in stderr, stderr
    with pytest.warns(CutShortWarning, match=r"run.npz: the run was cut short at t = [0-9.]+ s \(step [0-9]+\): inter"):
        loaded = Trajectory.load(path)
    t_end, n = float(loaded.t[-1]), len(loaded.t)
    assert loaded.info.cut_short == {"t": t_end, "step": round(t_end * 1000), "cause": "interrupted"}
    assert loaded.info.t_end == t_end and t_end > 1.0 and n == round(t_end * 10) + 1
    assert f"stopped by SIGTERM at t = {t_end:.6g} s" in stderr
    code, err = plot(path, capsys)
    assert code == 0 and f"cut short at t = {t_end:.9g} s" in err and "Traceback" not in err


def read_until(process: subprocess.Popen, marker: bytes, timeout: float) -> bytes:
    """What the process wrote on stderr until ``marker`` appeared (or it ended, or ``timeout`` [s] passed)."""
    import select

    text, deadline = b"", time.monotonic() + timeout
    descriptor = process.stderr.fileno()
    while marker not in text and time.monotonic() < deadline:
        if select.select([descriptor], [], [], 0.1)[0]:
            chunk = os.read(descriptor, 4096)
            if not chunk:
                break
            text += chunk
    return text


def test_an_older_info_stopped_is_shown_without_error(tmp_path, capsys):
    """A file saved from a stream cut short before ``info.cut_short`` holds ``info.stopped = {"reason": "stream cut
    off", "t": ...}`` (no error class): ``pinstab plot`` shows it (it ended in ``KeyError: 'error'``)."""
    arrays = saved(tmp_path)
    info = RunInfo.from_json(str(arrays["info"]), "good.npz")
    info.stopped = {"reason": "stream cut off", "t": 0.02}
    (tmp_path / "old.npz").write_bytes(npz_bytes({**arrays, "info": np.array(json.dumps(info.to_dict()))}))
    capsys.readouterr()
    code = main(["plot", str(tmp_path / "old.npz"), "-o", str(tmp_path / "chart.png")])
    out, err = capsys.readouterr()
    assert code == 0 and "stopped    stream cut off at t = 0.02 s\n" in out and "Traceback" not in err


@pytest.mark.parametrize(
    ("stopped", "text"),
    [
        ({"reason": "stream cut off"}, "stream cut off"),
        (
            {"reason": "contact failure", "t": 0.5, "error": "PainleveError"},
            "contact failure at t = 0.5 s (PainleveError)",
        ),
        ({}, "stopped"),
    ],
)
def test_stopped_text_leaves_out_what_it_lacks(stopped, text):
    from pinstab.cli import stopped_text

    assert stopped_text(stopped) == text


# --- damaged files --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def streams(tmp_path_factory) -> dict[str, bytes]:
    """The bytes of a complete stream and of a killed one."""
    folder = tmp_path_factory.mktemp("streams")
    simulate("fourbar", duration=0.5, stream=folder / "complete.h5")
    return {"complete": (folder / "complete.h5").read_bytes(), "killed": killed_stream(folder).read_bytes()}


def damaged_heap(data: bytes) -> bytes:
    """``data`` with the free space of its first global heap collection given size 0 (HDF5 2.0 then loops forever
    reading an attribute)."""
    data = bytearray(data)
    start = data.find(GLOBAL_HEAP)
    end, at = start + int.from_bytes(data[start + 8 : start + 16], "little"), start + 16
    while int.from_bytes(data[at : at + 2], "little") != 0:
        at += 16 + -(-int.from_bytes(data[at + 8 : at + 16], "little") // 8) * 8
        assert at < end
    data[at + 8 : at + 16] = bytes(8)
    return bytes(data)


def damaged_header(data: bytes) -> bytes:
    """``data`` with a byte of its root group's object header flipped (a checksum that no longer matches)."""
    data = bytearray(data)
    root = int.from_bytes(data[36:44], "little")  # superblock v3: the root group's object header address
    assert data[root : root + 4] == b"OHDR"
    data[root + 20] ^= 0xFF
    return bytes(data)


HDF5_CASES = {  # name -> (the file's bytes from the two streams, a phrase of the error)
    "random bytes": (lambda s: np.random.default_rng(0).bytes(5000), "not a readable HDF5 run file"),
    "empty": (lambda s: b"", "not a readable HDF5 run file"),
    "HDF5 signature then random bytes": (
        lambda s: s["complete"][:8] + np.random.default_rng(1).bytes(5000),
        "not a readable HDF5 run file",
    ),
    "complete stream cut to its superblock": (lambda s: s["complete"][:30], "its superblock cut short"),
    "complete stream cut at 150 bytes": (lambda s: s["complete"][:150], "a truncated or damaged HDF5 file: 150 bytes"),
    "complete stream cut in half": (lambda s: s["complete"][: len(s["complete"]) // 2], "a truncated or damaged"),
    "complete stream less its last byte": (lambda s: s["complete"][:-1], "a truncated or damaged"),
    "killed stream cut at 150 bytes": (lambda s: s["killed"][:150], "a truncated or damaged HDF5 file: 150 bytes"),
    "killed stream cut in half": (lambda s: s["killed"][: len(s["killed"]) // 2], "a truncated or damaged"),
    "complete stream, global heap damaged": (lambda s: damaged_heap(s["complete"]), "holds an empty free space"),
    "killed stream, global heap damaged": (lambda s: damaged_heap(s["killed"]), "holds an empty free space"),
    "complete stream, object header damaged": (lambda s: damaged_header(s["complete"]), "a damaged HDF5 run file"),
    "killed stream, object header damaged": (lambda s: damaged_header(s["killed"]), "a damaged HDF5 run file"),
}


@pytest.mark.parametrize("case", list(HDF5_CASES))
def test_a_damaged_hdf5_file_is_named_in_bounded_time(tmp_path, streams, case):
    """Each damaged file: ``pinstab plot`` and ``record --from`` exit 2 naming the file and what is wrong, no
    traceback, each in a fresh process within 30 s (a damaged global heap looped forever in HDF5; a killed stream's
    damaged header was retried some 70 s); ``Trajectory.load`` raises PinstabError."""
    make, phrase = HDF5_CASES[case]
    path = tmp_path / "run.h5"
    path.write_bytes(make(streams))
    plot_argv = ["plot", str(path), "-o", str(tmp_path / "c.png")]
    for command in (plot_argv, ["record", "fourbar", "--from", str(path), "-o", str(tmp_path / "p.html")]):
        start = time.monotonic()
        argv = [sys.executable, "-m", "pinstab.cli", *command]
        done = subprocess.run(argv, env=ENV, capture_output=True, text=True, timeout=30)
        assert done.returncode == 2 and phrase in done.stderr and str(path) in done.stderr, done.stderr
        assert "Traceback" not in done.stderr and time.monotonic() - start < 30
    with pytest.raises(PinstabError, match=re.escape(phrase)):
        Trajectory.load(path)


def test_an_hdf5_file_of_something_else_is_named(tmp_path, capsys):
    with h5py.File(tmp_path / "other.h5", "w") as file:
        file["t"] = np.zeros(3)
    code, err = plot(tmp_path / "other.h5", capsys)
    assert code == 2 and "other.h5: not a pinstab run file (format None, no step, q, v" in err
    with h5py.File(tmp_path / "scalar.h5", "w") as file:
        for name in ("t", "step", "q", "v", "correction_iterations", "multipliers", "position_drift",
                     "velocity_drift", "energy", "spectral_radius"):  # fmt: skip
            file[name] = 1.0
        file.attrs.update(format="pinstab-stream", info=json.dumps(RunInfo("s", "m", "i", "x", 1e-3).to_dict()))
    code, err = plot(tmp_path / "scalar.h5", capsys)
    assert code == 2 and "scalar.h5: dataset 't' holds a single value, not a row per sample" in err


def saved(tmp_path: Path) -> dict[str, np.ndarray]:
    """The arrays of a short run saved by ``--save``."""
    simulate("fourbar", duration=0.02).save(tmp_path / "good.npz")
    with np.load(tmp_path / "good.npz") as data:
        return dict(data)


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


def with_row(array: np.ndarray, row: int, value: float) -> np.ndarray:
    changed = array.astype(float).copy()
    changed[row] = value
    return changed


NPZ_CASES = {  # name -> (the file's bytes from the saved arrays, a phrase of the error)
    "truncated zip": (lambda a: npz_bytes(a)[:-100], "not an NPZ archive, or a truncated one"),
    "half a zip": (lambda a: npz_bytes(a)[: len(npz_bytes(a)) // 2], "not an NPZ archive, or a truncated one"),
    "no q": (lambda a: npz_bytes({k: v for k, v in a.items() if k != "q"}), "not a pinstab trajectory file (no q;"),
    "q of one sample too few": (lambda a: npz_bytes({**a, "q": a["q"][:-1]}), "array 'q' (shape (20, 3), float64)"),
    "t not finite": (
        lambda a: npz_bytes({**a, "t": with_row(a["t"], 5, np.nan)}),
        "array 't' is not finite at sample 5",
    ),
    "t infinite at the end": (lambda a: npz_bytes({**a, "t": with_row(a["t"], -1, np.inf)}), "'t' is not finite at"),
    "q not finite": (lambda a: npz_bytes({**a, "q": with_row(a["q"], 3, np.nan)}), "'q' is not finite at sample 3 of"),
    "v infinite": (lambda a: npz_bytes({**a, "v": with_row(a["v"], 0, -np.inf)}), "'v' is not finite at sample 0 of"),
    "t going back": (lambda a: npz_bytes({**a, "t": a["t"][::-1].copy()}), "sample 1 (t = 0.019 s) is before"),
    "info not JSON": (lambda a: npz_bytes({**a, "info": np.array("{not json")}), "the run info is not JSON"),
    "info of a wrong type": (
        lambda a: npz_bytes({**a, "info": np.array(json.dumps({**json.loads(str(a["info"])), "dt": "1e-3"}))}),
        'run info: dt must be a number, got "1e-3"',
    ),
    "object array": (lambda a: npz_bytes({**a, "q": np.array([None], dtype=object)}), "Object arrays cannot be loaded"),
    "a CSV": (lambda a: b"t,q\n0,1\n", "not a pinstab trajectory file (not an NPZ archive"),
    "a binary file": (lambda a: np.random.default_rng(2).bytes(3000), "not a pinstab trajectory file (not an NPZ"),
}


@pytest.mark.parametrize("case", list(NPZ_CASES))
def test_a_damaged_npz_is_named(tmp_path, capsys, case):
    """Each damaged ``--save`` file (and a CSV given as a run): exit 2 from ``pinstab plot`` naming the file and
    what is wrong; ``Trajectory.load`` raises PinstabError."""
    make, phrase = NPZ_CASES[case]
    suffix = ".csv" if case == "a CSV" else ".npz"
    path = tmp_path / f"run{suffix}"
    path.write_bytes(make(saved(tmp_path)))
    code, err = plot(path, capsys)
    assert code == 2 and f"{path}: " in err and phrase in err and "Traceback" not in err, err
    with pytest.raises(PinstabError, match=re.escape(phrase)):
        Trajectory.load(path)


def test_damaged_bytes_in_an_npz_member_are_named(tmp_path):
    """Bytes of the stored ``q`` member flipped one at a time (every 15th): a PinstabError (an inflate error or a CRC
    that does not match), never zlib's or zipfile's own exception. (Its last byte is left: a flip there may fall in
    the deflate stream's padding bits, leaving the data whole.)"""
    simulate("fourbar", duration=0.02).save(tmp_path / "good.npz")
    data = (tmp_path / "good.npz").read_bytes()
    with zipfile.ZipFile(tmp_path / "good.npz") as archive:
        member = archive.getinfo("q.npy")
    local = member.header_offset  # the local header: 30 bytes, then the name and its own extra field
    start = local + 30 + int.from_bytes(data[local + 26 : local + 28], "little")
    start += int.from_bytes(data[local + 28 : local + 30], "little")
    for offset in range(start, start + member.compress_size - 1, 15):
        damaged = bytearray(data)
        damaged[offset] ^= 0xFF
        (tmp_path / "bad.npz").write_bytes(damaged)
        with pytest.raises(PinstabError, match="bad.npz: not a readable pinstab trajectory file"):
            Trajectory.load(tmp_path / "bad.npz")


def test_a_diverged_runs_failed_step_is_left_out_with_a_warning(tmp_path, capsys):
    """A last sample whose state is not finite (a diverged run's failed step, which a stream keeps and ``--save``
    leaves out) is left out with a warning: plot and record read the run up to the sample before (record failed in
    meshcat's quaternion of a NaN pose); a state not finite before the last sample is a damaged file."""
    arrays = saved(tmp_path)
    arrays["q"] = with_row(arrays["q"], -1, np.nan)
    (tmp_path / "diverged.npz").write_bytes(npz_bytes(arrays))
    with pytest.warns(PinstabWarning, match=r"the last sample \(t = 0.02 s\) is not finite"):
        loaded = Trajectory.load(tmp_path / "diverged.npz")
    assert len(loaded.t) == 20 and np.isfinite(loaded.q).all() and len(loaded.energy) == 20
    code, err = record_from(tmp_path / "diverged.npz", capsys)
    assert code == 0 and "read up to the sample before (t = 0.019 s)" in err
