"""``pinstab sweep``: grids, rows, the hold/slip boundary of ``pinch`` against its closed form, resuming a killed
sweep, a Dask scheduler started here, Parquet (with pyarrow)."""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pinstab.bench.sweep import run_figures, run_point, run_sweep
from pinstab.bench.sweep_grid import check_sweep, parse_grid
from pinstab.bench.sweep_table import read_rows, table_rows
from pinstab.cli import main
from pinstab.errors import PinstabError, SceneError
from pinstab.generators import GRAVITY

ROOT = Path(__file__).resolve().parents[1]
MUS = (0.05, 0.15, 0.25, 0.35, 0.45, 0.55, 0.65, 0.75)
SQUEEZES = (0.3, 0.7, 1.1, 1.5, 1.9, 2.3, 2.7, 3.1)  # 2 mu F = m g = 0.981 N falls on no point
GRIDS = [f"mu={','.join(map(str, MUS))}", f"squeeze={','.join(map(str, SQUEEZES))}"]
SHORT = ["--param", "duration=0.02", "--quiet"]
MASS = 0.1  # [kg] pinch's default block


def holds(mu: float, squeeze: float) -> bool:
    """pinch's closed form: the block holds iff the two contacts' friction 2 mu F reaches its weight m g."""
    return 2 * mu * squeeze >= MASS * GRAVITY


def env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


def test_grid_values_are_toml_scalars():
    assert parse_grid("N=10,20") == ("N", [10, 20])
    assert parse_grid("method=baumgarte,projection") == ("method", ["baumgarte", "projection"])
    assert parse_grid("dt=1e-3, 5e-4") == ("dt", [1e-3, 5e-4])
    for bad in ("mu", "=1,2", "mu=1,,2", "mu=2,2.0"):
        with pytest.raises(PinstabError, match="--grid"):
            parse_grid(bad)


def test_refusals_name_the_item_and_the_valid_ones(tmp_path):
    with pytest.raises(PinstabError, match=r"unknown name 'friction'; valid names: mu, squeeze, mass, method"):
        check_sweep("pinch", {"friction": [0.1]}, {})
    with pytest.raises(SceneError, match=r"sweep point mu=-1: generator pinch: parameter mu must be a number in \[0"):
        check_sweep("pinch", {"mu": [0.5, -1]}, {})
    with pytest.raises(PinstabError, match="integrator 'rk5' unknown; valid: .*rk4"):
        check_sweep("nfourbar", {"N": [2]}, {"integrator": "rk5"})
    with pytest.raises(PinstabError, match="dt takes a float"):
        check_sweep("nfourbar", {"dt": [1e-3, "fast"]}, {})
    with pytest.raises(PinstabError, match="method set, but the contacts are event-driven"):
        check_sweep("pinch", {"mu": [0.5]}, {"method": "baumgarte"})
    with pytest.raises(PinstabError, match="mu is both swept"):
        check_sweep("pinch", {"mu": [0.5]}, {"mu": 0.3})
    assert main(["sweep", "pinch", "--grid", "mu=0.1", "--out", str(tmp_path / "x.txt")]) == 2
    assert main(["sweep", "pinch", "--grid", "mu=0.1", "--out", str(tmp_path / "x.csv"), "--chart", "mu", "grip"]) == 2
    assert not list(tmp_path.iterdir())


def test_sliding_time_from_contact_events():
    """Two contacts: a slides over [0.1, 0.4], b over [0.3, 0.6] and from 0.9 to the end 1.0 -> 0.6 s."""
    events = [
        {"t": 0.0, "contact": "a", "to": "sticking"},
        {"t": 0.0, "contact": "b", "to": "sticking"},
        {"t": 0.1, "contact": "a", "to": "sliding"},
        {"t": 0.3, "contact": "b", "to": "sliding"},
        {"t": 0.4, "contact": "a", "to": "sticking"},
        {"t": 0.6, "contact": "b", "to": "separated"},
        {"t": 0.9, "contact": "b", "to": "sliding"},
    ]
    figures = run_figures({"contact_events": events, "t_end": 1.0, "stopped": None})
    assert figures["sliding_s"] == pytest.approx(0.6, abs=1e-12)
    assert figures["held"] is False and figures["contact_events"] == 7
    assert run_figures({"contact_events": events[:2], "t_end": 1.0})["held"] is True


def test_point_rows_hold_slip_and_failure():
    """A point below and one above the closed-form boundary; a run that diverges is a row with the error."""
    for mu, squeeze in ((0.3, 1.0), (0.6, 1.0)):
        row = run_point("pinch", {"mu": mu, "squeeze": squeeze}, {"duration": 0.05}, ("mu", "squeeze", "mass"))
        assert row["held"] is holds(mu, squeeze) and row["error"] == ""
        assert row["sliding_s"] == pytest.approx(0.0 if holds(mu, squeeze) else 0.05, abs=1e-12)
    failed = run_point("fourbar", {"drift_limit": 1e-14}, {"method": "none", "duration": 0.5, "dt": 0.01}, ())
    assert failed["error"].startswith("DivergenceError") and failed["steps"] is None


def _sweep_command(out: Path, *extra: str) -> list[str]:
    grids = [item for grid in GRIDS for item in ("--grid", grid)]
    return ["sweep", "pinch", *grids, "--out", str(out), *SHORT, *extra]


def test_killed_sweep_resumes_and_draws_the_boundary(tmp_path):
    """64 (mu, squeeze) points on a LocalCluster: killed (SIGKILL, the whole process group) after some rows,
    re-run: no point twice, all 64 there, each held iff 2 mu F >= m g; the chart drawn from the table."""
    out = tmp_path / "pinch.csv"
    command = [sys.executable, "-m", "pinstab.cli", *_sweep_command(out)]
    process = subprocess.Popen(command, env=env(), start_new_session=True, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 40
        while time.monotonic() < deadline and process.poll() is None:
            if out.exists() and out.read_text().count("\n") > 6:  # the header and at least 6 rows
                break
            time.sleep(0.02)
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    assert process.returncode == -signal.SIGKILL, process.stderr.read().decode()
    before = len(list(read_rows(out)))
    assert 6 <= before < 64
    png = tmp_path / "boundary.png"
    args = _sweep_command(out, "--chart", "mu", "squeeze", "--color", "held", "--chart-file", str(png), "--json")
    assert main(args) == 0
    rows = table_rows(out)
    keys = [(row["mu"], row["squeeze"]) for row in rows]
    assert len(keys) == len(set(keys)) == 64 and set(keys) == set(itertools.product(MUS, SQUEEZES))
    assert all(row["held"] is holds(row["mu"], row["squeeze"]) and row["error"] is None for row in rows)
    assert {row["held"] for row in rows} == {True, False}
    assert png.stat().st_size > 10_000
    again = run_sweep("pinch", dict(parse_grid(g) for g in GRIDS), out, {"duration": 0.02})
    assert (again["skipped"], again["ran"]) == (64, 0)


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """A ``dask scheduler`` and a ``dask worker`` (one process, one thread) started here; their address."""
    folder = tmp_path_factory.mktemp("dask")
    dask = Path(sys.executable).with_name("dask")
    file = folder / "scheduler.json"
    common = ["--no-dashboard"]
    started = [
        subprocess.Popen(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--scheduler-file", file, *common],
            env=env(),
            stderr=subprocess.DEVNULL,
        )
    ]
    deadline = time.monotonic() + 30
    while not file.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    started.append(
        subprocess.Popen(
            [dask, "worker", "--scheduler-file", file, "--nworkers", "1", "--nthreads", "1", *common],
            env=env(),
            stderr=subprocess.DEVNULL,
            cwd=folder,
        )
    )
    yield json.loads(file.read_text())["address"]
    for process in reversed(started):
        process.terminate()
        process.wait(timeout=30)


def test_sweep_on_a_scheduler(scheduler, tmp_path):
    out = tmp_path / "pinch.csv"
    args = ["sweep", "pinch", "--grid", "mu=0.15,0.55", "--grid", "squeeze=0.7,3.1", "--out", str(out), *SHORT]
    assert main([*args, "--scheduler", scheduler]) == 0
    rows = table_rows(out)
    assert sorted((r["mu"], r["squeeze"], r["held"]) for r in rows) == [
        (mu, squeeze, holds(mu, squeeze)) for mu in (0.15, 0.55) for squeeze in (0.7, 3.1)
    ]


def test_parquet_table(scheduler, tmp_path):
    pytest.importorskip("pyarrow")
    out = tmp_path / "pinch.parquet"

    def args(squeezes: str) -> list[str]:
        grids = ["--grid", "mu=0.15,0.55", "--grid", f"squeeze={squeezes}"]
        return ["sweep", "pinch", *grids, "--out", str(out), *SHORT, "--scheduler", scheduler, "--json"]

    assert main(args("3")) == 0
    assert main(args("3,0.7")) == 0  # the squeeze 3 points skipped: 3 and the Parquet double 3.0 are one key
    rows = table_rows(out)
    assert sorted((r["mu"], r["squeeze"], r["held"]) for r in rows) == [
        (mu, squeeze, holds(mu, squeeze)) for mu in (0.15, 0.55) for squeeze in (0.7, 3.0)
    ]
    assert not out.with_name(out.name + ".partial.csv").exists()


def test_parquet_needs_pyarrow(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    with pytest.raises(PinstabError, match=r"pip install 'pinstab\[sweep\]'"):
        run_sweep("pinch", {"mu": [0.5]}, tmp_path / "t.parquet")


def test_a_parquet_table_of_another_sweep_is_refused_and_kept(tmp_path):
    """Resuming into a Parquet file of other columns: a PinstabError naming the file, no journal written, the
    file untouched (it used to end in a raw ValueError and leave a journal that the next run took)."""
    pyarrow = pytest.importorskip("pyarrow")
    parquet = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "other.parquet"
    parquet.write_table(pyarrow.table({"x": [1.0], "y": [2.0]}), out)
    before = out.read_bytes()
    with pytest.raises(PinstabError, match=r"other.parquet holds another sweep's table \(columns x, y\)"):
        run_sweep("pinch", {"mu": [0.5]}, out)
    assert out.read_bytes() == before and not out.with_name(out.name + ".partial.csv").exists()


def test_a_sweep_with_failed_points_exits_6(scheduler, tmp_path, capsys):
    """One point of two diverges (a drift limit of 1e-14 on an unstabilized four-bar, as in
    test_point_rows_hold_slip_and_failure): the sweep ends with exit 6 naming it; a re-run that skips both still
    does."""
    out = tmp_path / "fourbar.csv"
    fixed = ["--param", "method=none", "--param", "duration=0.5", "--param", "dt=0.01"]
    args = ["sweep", "fourbar", "--grid", "drift_limit=1e-14,1", "-o", str(out), *fixed, "--quiet"]
    assert main([*args, "--scheduler", scheduler]) == 6
    assert "1 of 2 points failed; their rows in" in capsys.readouterr().err
    errors = {row["drift_limit"]: row["error"] or "" for row in table_rows(out)}
    assert errors[1e-14].startswith("DivergenceError") and errors[1] == ""
    assert main([*args, "--scheduler", scheduler, "--json"]) == 6
    captured = capsys.readouterr()
    assert (json.loads(captured.out)["skipped"], json.loads(captured.out)["failed_before"]) == (2, 1)
    assert "1 of 2 points failed, 1 of them in an earlier run" in captured.err
