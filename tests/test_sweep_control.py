"""Sweeps under control (issue 34): every grid point checked before any runs with run's own messages, a bounded
number of points, the memory budgeted, SIGINT/SIGTERM stopping after the points in flight with the table kept, and a
table that is not one (binary, malformed, corrupt Parquet) a named error."""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import pytest
from test_catalogue import Case, run_case

from conftest import interruptible
from pinstab.bench import sweep_grid
from pinstab.bench.cluster import dask_client
from pinstab.bench.sweep import KEY_BYTES, KEY_VALUE_BYTES, WORKER_BYTES, columns, run_point, run_sweep
from pinstab.bench.sweep_grid import MAX_POINTS, check_sweep
from pinstab.bench.sweep_table import SweepTable, read_rows, table_rows
from pinstab.cli import main
from pinstab.constraints.joint_limits import joint_limits
from pinstab.errors import MemoryBudgetError, PinstabError
from pinstab.integration import TimeGrid
from pinstab.memory import format_size, memory_limit
from pinstab.scene import load_scene
from pinstab.simulate import simulate
from pinstab.simulate.loop import run_memory

ROOT = Path(__file__).resolve().parents[1]
PINCH = ("mu", "squeeze", "mass")


def env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


def run_refusal(scene: str, values: dict) -> PinstabError:
    """The error that a run of ``scene`` with ``values`` (run options, or scene parameters of pinch) ends in."""
    with pytest.raises(PinstabError) as refused:
        if scene == "pinch":
            load_scene("pinch", **values)
        else:
            simulate(scene, **values)
    return refused.value


# (scene, --grid, the point's words in the message, the run that refuses the same value)
GRID_REFUSALS = [
    ("fourbar", "dt=0,1e-3", "dt=0", {"dt": 0}),
    ("fourbar", "duration=-1", "duration=-1", {"duration": -1}),
    ("fourbar", "record_every=0", "record_every=0", {"record_every": 0}),
    ("fourbar", "rtol=1e-6,0", "rtol=0", {"rtol": 0}),
    ("fourbar", "atol=2", "atol=2", {"atol": 2}),
    ("fourbar", "drift_limit=1,-1", "drift_limit=-1", {"drift_limit": -1}),
    ("fourbar", "kp=100,-1", "kp=-1", {"kp": -1}),
    ("fourbar", "kd=1e400", "kd=inf", {"kd": float("inf")}),  # TOML reads 1e400 as inf
    ("fourbar", "dt=nan", "dt=nan", {"dt": float("nan")}),
    ("pinch", "mu=0.5,1e200", "mu=1e+200", {"mu": 1e200}),
    ("pinch", "squeeze=1,-2", "squeeze=-2", {"squeeze": -2}),
]


@pytest.mark.parametrize("scene,grid,point,values", GRID_REFUSALS, ids=[g[1] for g in GRID_REFUSALS])
def test_a_grid_value_is_refused_before_any_work_with_runs_message(scene, grid, point, values, tmp_path, capsys):
    """The issue's ``--grid dt=0,1e-3`` (duration=-1, record_every=0...) used to exit 0 or 6 with error rows: now
    exit 2 before any point runs (no table, no cluster: in-process, fast), the message naming the grid value and
    ending with the message the run gives for the same value, of the same class."""
    refused = run_refusal(scene, values)
    started = time.perf_counter()
    case = Case(grid, f"sweep {scene} --grid {grid} -o {{tmp}}/t.csv --quiet", type(refused).__name__, "")
    code, error, err = run_case(case, tmp_path, capsys)
    assert time.perf_counter() - started < 5
    assert code == 2 and "Traceback" not in err and not (tmp_path / "t.csv").exists()
    assert error == type(refused).__name__
    assert f"pinstab sweep: error: sweep point {point}: {refused}" in err


def test_every_combination_is_checked_not_only_each_value(monkeypatch):
    """dt = 1e-9 s runs for a millisecond, not for 1e5 s (1e14 steps): the point is refused with run's message, naming
    both values; and the scene is loaded once for each combination of its swept parameters (6 for 3 x 2)."""
    check_sweep("fourbar", {"dt": [1e-9], "duration": [1e-3]}, {})
    refused = run_refusal("fourbar", {"dt": 1e-9, "duration": 1e5})
    with pytest.raises(PinstabError) as caught:
        check_sweep("fourbar", {"dt": [1e-9], "kp": [1, 2], "duration": [1e-3, 1e5]}, {})
    assert str(caught.value) == f"sweep point dt=1e-09, duration=100000.0: {refused}"
    loaded = []
    original = sweep_grid.load_scene

    def counted(name, **parameters):
        loaded.append(parameters)
        return original(name, **parameters)

    monkeypatch.setattr(sweep_grid, "load_scene", counted)
    check_sweep("pinch", {"mu": [0.1, 0.2, 0.3], "squeeze": [1, 2], "dt": [1e-3, 2e-3]}, {"mass": 0.2})
    combinations = [params for params in loaded if set(params) == set(PINCH)]
    assert sorted((p["mu"], p["squeeze"]) for p in combinations) == list(itertools.product([0.1, 0.2, 0.3], [1, 2]))
    assert {p["mass"] for p in combinations} == {0.2}


def test_the_range_boundaries_pass():
    """The largest friction coefficient (pinch's mu = 10), the smallest rtol above 1e-14: accepted."""
    assert check_sweep("pinch", {"mu": [0, 10]}, {"duration": 0.01}).points == 2
    assert check_sweep("fourbar", {"rtol": [1.01e-14, 0.99]}, {}).points == 2


def test_more_points_than_the_limit_are_refused_at_once(tmp_path, capsys):
    """The issue's 10^6-point sweep grew memory with no row for 75 s: refused in well under a second now, naming the
    count and the flag; the limit itself passes the checks, one more point does not."""
    values = ",".join(str(0.001 * i) for i in range(1, 1001))
    case = Case("million", f"sweep pinch --grid mu={values} --grid squeeze={values} -o {{tmp}}/t.csv", "", "")
    started = time.perf_counter()
    code, error, err = run_case(case, tmp_path, capsys)
    assert time.perf_counter() - started < 3
    assert code == 2 and error == "PinstabError" and not (tmp_path / "t.csv").exists()
    assert "1,000,000 points (1000 mu x 1000 squeeze) exceed the limit of 10,000" in err
    assert "--max-points 1000000" in err
    side = int(MAX_POINTS**0.5)
    grids = {"drift_limit": [1.0 + i for i in range(side)], "kp": [float(i) for i in range(side)]}
    assert check_sweep("fourbar", grids, {}).points == MAX_POINTS == side * side
    with pytest.raises(PinstabError, match=f"{MAX_POINTS + side:,} points .* exceed the limit of {MAX_POINTS:,}"):
        check_sweep("fourbar", {**grids, "drift_limit": [*grids["drift_limit"], 0.5]}, {})
    zero = Case("zero", "sweep fourbar --grid kp=1 --max-points 0 -o {tmp}/t.csv", "", "")
    code, _, err = run_case(zero, tmp_path, capsys)
    assert code == 2 and "max_points (--max-points) must be a whole number >= 1, got 0" in err


def test_the_memory_budget_refuses_before_any_work(tmp_path, capsys):
    """Under --memory-limit 300MB the two local workers' estimate alone exceeds it: MemoryBudgetError, exit 2,
    nothing written; its run item is the run's own estimate of the point that keeps the most samples."""
    scene = load_scene("fourbar")
    longest = run_memory(scene, TimeGrid.of(1e-3, 2.0), 1, None)
    expected = 2 * (WORKER_BYTES + sum(longest.values()))
    case = Case("memory", "sweep fourbar --grid duration=1,2 --memory-limit 300MB -o {tmp}/t.csv", "", "")
    code, error, err = run_case(case, tmp_path, capsys)
    assert code == 2 and error == "MemoryBudgetError" and not (tmp_path / "t.csv").exists()
    assert f"a sweep of 2 points of scene fourbar needs about {format_size(expected)}" in err
    assert "2,002 kept samples" in err
    with memory_limit("300MB"), pytest.raises(MemoryBudgetError):
        run_sweep("fourbar", {"duration": [1, 2]}, tmp_path / "t.csv")


def test_the_table_keys_estimate_bounds_their_memory(tmp_path):
    """The keys a resumed table holds (measured with tracemalloc) stay under the estimate of sweep_memory, and
    above a third of it (an estimate, not a guess)."""
    grids = {"mu": [], "squeeze": [], "mass": []}
    out = tmp_path / "t.csv"
    rows = 20_000
    with open(out, "w") as handle:
        handle.write(",".join(columns(grids)) + "\n")
        for i in range(rows):
            handle.write(f"{0.001 * i},{1 + 0.01 * i},0.1" + "," * (len(columns(grids)) - 3) + "\n")
    tracemalloc.start()
    table = SweepTable(out, columns(grids), len(grids))
    used = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    assert len(table.done) == rows
    estimate = rows * (KEY_BYTES + KEY_VALUE_BYTES * len(grids))
    assert estimate / 3 < used <= estimate, (used, estimate)


def test_a_worker_fits_its_estimate():
    """The local workers, each having run the four-bar for a second: their resident memory stays under
    WORKER_BYTES and the run's estimate, and above half of it."""

    def resident() -> int:
        with open("/proc/self/status") as status:
            return next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmRSS:"))

    scene = load_scene("fourbar")
    estimate = WORKER_BYTES + sum(run_memory(scene, TimeGrid.of(1e-3, 1.0), 1, None).values())
    with dask_client(None, "sweep", "") as client:
        rows = client.run(run_point, "fourbar", {"duration": 1.0}, {}, ()).values()  # on each worker
        assert [(row["error"], row["t_end"]) for row in rows] == [("", 1.0)] * 2
        sizes = client.run(resident).values()
    assert all(WORKER_BYTES / 2 < size < estimate for size in sizes), (sizes, estimate)


# -- tables that are not tables ----------------------------------------------------------------------------------
HEADER = ",".join(columns(["kp"]))
CELLS = len(columns(["kp"]))
BAD_TABLES = [
    ("binary.csv", bytes(range(256)) * 40, "line 1: a NUL byte (binary data)"),
    ("latin1.csv", f"{HEADER}\n1.0{',' * (CELLS - 1)}\n\xe9t\xe9\n".encode("latin-1"), "line 3: not UTF-8 text"),
    ("cells.csv", f"{HEADER}\n1.0,2.0\n".encode(), f"line 2: 2 cell(s), the header {CELLS}"),
    ("field.csv", f"{HEADER}\n{'9' * 200_000}{',' * (CELLS - 1)}\n".encode(), "line 2: field larger than field limit"),
    ("noheader.csv", b"kp,steps", "line 1: no complete header line"),
    ("long.csv", b"x" * (2 << 20), "line 1: longer than 1,048,576 bytes"),
]


@pytest.mark.parametrize("name,content,phrase", BAD_TABLES, ids=[t[0] for t in BAD_TABLES])
def test_a_table_that_is_not_one_is_a_named_error_and_kept(name, content, phrase, tmp_path, capsys):
    """The issue's binary --out CSV ended in UnicodeDecodeError: now exit 2 naming the file and the line, the file
    untouched, no cluster started; the chart's reader names it the same way."""
    out = tmp_path / name
    out.write_bytes(content)
    case = Case(name, f"sweep fourbar --grid kp=1,2 -o {out} --quiet", "", "")
    code, error, err = run_case(case, tmp_path, capsys)
    assert code == 2 and error == "PinstabError" and "Traceback" not in err
    assert f"{out} is not a sweep table: {phrase}" in err
    assert out.read_bytes() == content
    with pytest.raises(PinstabError, match="is not a sweep table"):
        table_rows(out)


def test_a_corrupt_parquet_table_is_a_named_error(tmp_path, capsys):
    pytest.importorskip("pyarrow")
    out = tmp_path / "t.parquet"
    out.write_bytes(b"PAR1" + bytes(range(256)) * 8)
    case = Case("parquet", f"sweep fourbar --grid kp=1,2 -o {out} --quiet", "", "")
    code, error, err = run_case(case, tmp_path, capsys)
    assert code == 2 and error == "PinstabError" and f"{out} is not a sweep table: not a Parquet file" in err
    with pytest.raises(PinstabError, match="not a Parquet file"):
        table_rows(out)


# -- stopping --------------------------------------------------------------------------------------------------------
GROUPS: list[int] = []  # process groups of the sweeps this module started


@pytest.fixture(autouse=True)
def no_sweep_outlives_its_test():
    """Kill every sweep's process group (the CLI and its Dask workers) when its test ends, failed or not: a failed
    assertion before the signal would otherwise leave a million-point sweep running for hours."""
    yield
    while GROUPS:
        try:
            os.killpg(GROUPS.pop(), signal.SIGKILL)
        except ProcessLookupError:
            pass


def spawn(command: list[str], **popen) -> subprocess.Popen:
    """``command`` in a child process of its own group, killed with its group when the test ends."""
    process = subprocess.Popen(command, env=env(), start_new_session=True, stderr=subprocess.PIPE, **popen)
    GROUPS.append(process.pid)
    return process


def start_sweep(out: Path, *extra: str, **popen) -> subprocess.Popen:
    """A sweep of the four-bar over drift_limit (400 points of 0.2 s) in a child process of its own group."""
    grid = ",".join(str(i) for i in range(1, 401))
    command = [sys.executable, "-m", "pinstab.cli", "sweep", "fourbar", "--grid", f"drift_limit={grid}"]
    command += ["--param", "duration=0.2", "-o", str(out), "--quiet", *extra]
    return spawn(command, **popen)


def rows_in(out: Path) -> int:
    return out.read_bytes().count(b"\n") - 1 if out.exists() else 0


def wait_for_rows(process: subprocess.Popen, out: Path, rows: int, within: float = 30) -> float:
    """Wait until ``out`` holds ``rows`` rows; returns when [monotonic s]."""
    deadline = time.monotonic() + within
    while rows_in(out) < rows:
        assert process.poll() is None, process.stderr.read().decode()
        assert time.monotonic() < deadline, f"fewer than {rows} rows in {within} s"
        time.sleep(0.02)
    return time.monotonic()


def stopped(process: subprocess.Popen, within: float = 15) -> tuple[int, str, float]:
    """(exit code, stderr, seconds taken) of a child told to stop; killed (its group) if it does not."""
    started = time.monotonic()
    try:
        process.wait(timeout=within)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    return process.returncode, process.stderr.read().decode(), time.monotonic() - started


def kept_rows(out: Path, err: str, points: int) -> list[dict]:
    """The table's rows, checked: loadable, each point once, fewer than the sweep's points, as many as stderr says."""
    rows = table_rows(out)
    keys = [row["drift_limit"] for row in rows]
    assert len(set(keys)) == len(keys) < points
    assert all(row["error"] is None and row["t_end"] == pytest.approx(0.2) for row in rows)
    assert f"the sweep stopped after its points in flight; {len(rows)} new rows in {out}" in err
    return rows


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_stops_the_sweep_after_the_points_in_flight(signum, tmp_path):
    """SIGTERM to the sweep, or SIGINT to its whole process group (a terminal's Ctrl-C: the local workers get it
    too): exit 143 / 130 within seconds, the rows of the points in flight written (at least those there at the
    signal), the table loadable; a re-run resumes it and skips them."""
    out = tmp_path / "stop.csv"
    process = start_sweep(out, preexec_fn=interruptible)
    wait_for_rows(process, out, 8)
    before = rows_in(out)
    if signum == signal.SIGINT:
        os.killpg(process.pid, signum)
    else:
        process.send_signal(signum)
    code, err, taken = stopped(process)
    assert code == 128 + signum, err
    assert taken < 10 and "Traceback" not in err
    assert len(kept_rows(out, err, 400)) >= before


def test_a_sweep_of_a_million_points_writes_rows_at_once_and_stops_on_sigterm(tmp_path):
    """The issue's 10^6 points with the limit overridden: the first rows come within seconds (the points are not
    all submitted up front), the client's memory does not grow with the points, SIGTERM stops it."""
    values = ",".join(str(i) for i in range(1, 1001))
    out = tmp_path / "million.csv"
    command = [sys.executable, "-m", "pinstab.cli", "sweep", "fourbar", "--grid", f"drift_limit={values}"]
    command += ["--grid", f"kp={values}", "--param", "duration=0.01", "-o", str(out), "--quiet"]
    process = spawn([*command, "--max-points", "1000000"])
    started = time.monotonic()
    first = wait_for_rows(process, out, 1)
    assert first - started < 8

    def resident() -> int:
        status = Path(f"/proc/{process.pid}/status").read_text()
        return next(int(line.split()[1]) * 1024 for line in status.splitlines() if line.startswith("VmRSS:"))

    wait_for_rows(process, out, 20)
    size, rows = resident(), rows_in(out)
    time.sleep(1.5)
    grown, more = resident() - size, rows_in(out) - rows
    process.send_signal(signal.SIGTERM)
    code, err, taken = stopped(process)
    assert code == 143 and taken < 10, err
    assert more > 20 and grown < 20e6, (more, grown)
    rows = table_rows(out)
    assert len({(row["drift_limit"], row["kp"]) for row in rows}) == len(rows) > 40


def test_sigterm_writes_the_parquet_table(tmp_path):
    """Parquet: SIGTERM converts the journal to the Parquet file (atomically: no temporary file left, the journal
    removed), which loads with the rows so far."""
    pytest.importorskip("pyarrow")
    out = tmp_path / "stop.parquet"
    process = start_sweep(out)
    wait_for_rows(process, tmp_path / "stop.parquet.partial.csv", 5)
    process.send_signal(signal.SIGTERM)
    code, err, _ = stopped(process)
    assert code == 143 and [path.name for path in tmp_path.iterdir()] == [out.name], err
    assert len(kept_rows(out, err, 400)) >= 5


def test_kill9_leaves_a_parquet_journal_that_loads_and_resumes(tmp_path):
    """Parquet killed with -9: its journal holds the rows so far; table_rows reads them, each once, and a re-run's
    table takes them as done."""
    pytest.importorskip("pyarrow")
    out = tmp_path / "killed.parquet"
    journal = tmp_path / "killed.parquet.partial.csv"
    process = start_sweep(out)
    wait_for_rows(process, journal, 8)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    rows = table_rows(out)
    keys = [row["drift_limit"] for row in rows]
    assert len(set(keys)) == len(keys) >= 8 and len(list(read_rows(journal))) == len(rows)
    assert all(row["error"] is None and row["t_end"] == pytest.approx(0.2) for row in rows)
    assert SweepTable(out, columns(["drift_limit"]), 1).done == {(repr(float(key)),) for key in keys}


# -- what a run refuses once its system is built, checked before any point runs ------------------------------------
LIMITED = """\
[robot]
urdf_text = \"\"\"<robot name="pendulum"><link name="base"/>
  <link name="rod"><inertial><origin xyz="0 0 -0.5"/><mass value="2"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="rod"/><axis xyz="0 1 0"/>
    <limit lower="1.3" upper="3.0" effort="100" velocity="100"/></joint>
</robot>\"\"\"

[initial]
q = { hinge = 1.2 }
"""
APART = (("offset_b = [0.5, 0.0, 0.0]", "offset_b = [5.0, 0.0, 0.0]"),)  # the four-bar's rocker too far to close


def system_case(name: str, arguments: str, **scene) -> Case:
    """The case of ``pinstab sweep ARGUMENTS -o {tmp}/t.csv --quiet`` (``scene``: Case's changes or files)."""
    return Case(name, f"sweep {arguments} -o {{tmp}}/t.csv --quiet", "", "", **scene)


# (case, the point's words in the message, the simulate() keywords that make the same point)
SETUP_REFUSALS = [
    (
        system_case("method on another solver", "fourbar --grid method=pinocchio,baumgarte --param solver=dense"),
        "method=pinocchio",
        {"method": "pinocchio", "solver": "dense"},
    ),
    (
        system_case("corrector", "fourbar --grid solver=proxsuite,pinocchio --param method=mukharlyamov"),
        "solver=pinocchio",
        {"method": "mukharlyamov", "solver": "pinocchio"},
    ),
    (
        system_case("row kinds", "painleve-rod --grid solver=proxsuite,dense --param contacts=held"),
        "solver=dense",
        {"solver": "dense", "contacts": "held"},
    ),
    (
        system_case("automatic gains, rtol", "fourbar --grid method=baumgarte,mukharlyamov --param rtol=1e-6"),
        "method=mukharlyamov",
        {"method": "mukharlyamov", "rtol": 1e-6},
    ),
    (system_case("carried plane, held", "pinch --grid contacts=event,held"), "contacts=held", {"contacts": "held"}),
    (
        system_case("closures, stepping", "fourbar --grid contacts=held,stepping"),
        "contacts=stepping",
        {"contacts": "stepping"},
    ),
    (system_case("assembly", "{scene} --grid kp=1,2", changes=APART), "", {"kp": 1}),
    (
        system_case("limits", "{tmp}/limited.toml --grid dt=1e-3,2e-4", files=(("limited.toml", LIMITED),)),
        "",
        {},
    ),
]


@pytest.mark.parametrize("case,point,values", SETUP_REFUSALS, ids=[c[0].name for c in SETUP_REFUSALS])
def test_what_a_run_refuses_once_its_system_is_built_is_refused_before_any_point(case, point, values, tmp_path, capsys):
    """A method on a solver it does not run on, a solver that does not take the scene's rows or corrector, automatic
    gains under error control, contacts the scene cannot take, closures that cannot assemble, a start outside the
    joint limits: each used to end as error rows (exit 6) once the cluster ran them; now exit 2 before any work (no
    table, no cluster: in-process, fast), with the message simulate() gives for the same point, of the same class."""
    started = time.perf_counter()
    code, error, err = run_case(case, tmp_path, capsys)
    assert time.perf_counter() - started < 5
    if case.changes:
        scene = str(tmp_path / f"{case.base}-changed.toml")
    else:
        scene = str(tmp_path / case.files[0][0]) if case.files else case.argv.split()[1]
    with pytest.raises(PinstabError) as refused:
        simulate(scene, duration=1e-3, **values)
    assert code == 2 and "Traceback" not in err, err
    assert error == type(refused.value).__name__
    words = f"sweep point {point}: " if point else ""
    assert f"pinstab sweep: error: {words}{refused.value}\n" in err
    assert not list(tmp_path.glob("*.csv"))


def test_the_system_checks_pass_what_runs():
    """The combinations these checks refuse have neighbours that run: pinocchio on its solver, mukharlyamov with
    its gains under rtol, dense on held closures, the pendulum started inside its limits."""
    grids = {"method": ["pinocchio"], "solver": ["pinocchio"]}
    assert check_sweep("fourbar", grids, {}).points == 1
    fixed = {"method": "mukharlyamov", "kp": 100.0, "kd": 20.0, "rtol": 1e-6}
    assert check_sweep("fourbar", {"solver": ["proxsuite", "dense"]}, fixed).points == 2
    row = run_point("fourbar", {"solver": "dense"}, {**fixed, "duration": 0.01}, ())
    assert row["error"] == "" and row["t_end"] == pytest.approx(0.01)


def test_the_start_is_checked_for_each_scene_combination_and_contact_treatment(monkeypatch):
    """The contacts' system (run's contact_system, after held_limits) is checked once for each combination of the
    swept scene parameters and contact treatment, 3 mu x 2 squeeze x 2 contacts, each with the point's scene, and
    with the closures that the joint limits need on event-driven contacts only."""
    seen = []
    original = sweep_grid.contact_system

    def counted(scene, q0, v0, closures=False):
        seen.append((scene.parameters["mu"], scene.parameters["squeeze"], closures))
        return original(scene, q0, v0, closures)

    monkeypatch.setattr(sweep_grid, "contact_system", counted)
    grids = {"mu": [0.1, 0.2, 0.3], "squeeze": [1, 2], "contacts": ["event", "stepping"]}
    assert check_sweep("pinch", grids, {}).points == 12
    assert joint_limits(load_scene("pinch").model).limits  # held by event-driven contacts: their closures assembled
    expected = [(mu, squeeze, contacts == "event") for mu, squeeze, contacts in itertools.product(*grids.values())]
    assert sorted(seen) == sorted(expected)


# -- the checks' progress, and a signal during them -----------------------------------------------------------------
def test_the_checks_show_their_progress(monkeypatch, capsys):
    """With a progress bar (the command line without --quiet): the checks made of how many, on stderr; 6 scene
    combinations, each loaded and checked by every check of RUN_CHECKS once (no run option swept)."""
    monkeypatch.setattr(sweep_grid, "CHECK_BAR_DELAY", 0.0)
    check_sweep("pinch", {"mu": [0.1, 0.2, 0.3], "squeeze": [1, 2]}, {}, show_progress=True)
    total = 6 * (1 + len(sweep_grid.RUN_CHECKS))
    err = capsys.readouterr().err
    assert "checking the points" in err and f"{total}/{total}" in err
    check_sweep("pinch", {"mu": [0.1, 0.2, 0.3], "squeeze": [1, 2]}, {})
    assert capsys.readouterr().err == ""


def start_check(tmp_path: Path) -> tuple[subprocess.Popen, list[bytes]]:
    """A sweep of pinch over 100 mu x 100 squeeze (10^4 scene combinations, 20 s or more of checks) in a child of
    its own group, its progress bar on; returns it and the list its stderr is read into (a thread)."""
    import threading

    values = ",".join(str(0.01 * i) for i in range(1, 101))
    command = [sys.executable, "-m", "pinstab.cli", "sweep", "pinch", "--grid", f"mu={values}"]
    command += ["--grid", f"squeeze={values}", "-o", str(tmp_path / "t.csv")]
    process = spawn(command, preexec_fn=interruptible)
    chunks: list[bytes] = []
    threading.Thread(target=lambda: chunks.extend(iter(lambda: process.stderr.read1(256), b"")), daemon=True).start()
    return process, chunks


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_stops_the_checks_and_nothing_is_written(signum, tmp_path):
    """10^4 scene combinations take seconds to check (about 1.5 ms a load and its checks): the bar shows after
    CHECK_BAR_DELAY, and SIGTERM or Ctrl-C (SIGINT to the group) ends the sweep there, exit 143 / 130 in well
    under a second, saying how far the checks went, no traceback, no file written."""
    process, chunks = start_check(tmp_path)
    deadline = time.monotonic() + 20
    while b"checking the points" not in b"".join(chunks):
        assert process.poll() is None and time.monotonic() < deadline, b"".join(chunks).decode()
        time.sleep(0.05)
    if signum == signal.SIGINT:
        os.killpg(process.pid, signum)
    else:
        process.send_signal(signum)
    started = time.monotonic()
    try:
        code = process.wait(timeout=15)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        raise
    taken = time.monotonic() - started
    time.sleep(0.1)  # the reader thread's last chunk
    err = b"".join(chunks).decode()
    assert code == 128 + signum and taken < 3, err
    cause = "interrupted" if signum == signal.SIGINT else "stopped by SIGTERM"
    total = 10_000 * (1 + len(sweep_grid.RUN_CHECKS))
    assert f"pinstab sweep: {cause}; the sweep was still checking its points (" in err
    assert f" of {total:,} checks made): nothing was written" in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


# -- a point that kills its worker; the scheduler lost -------------------------------------------------------------
def test_a_point_that_kills_its_worker_is_a_named_error_row(tmp_path, capsys, monkeypatch):
    """A point whose run ends its worker process (os._exit, as a crash in compiled code or the kernel's OOM killer
    would) used to end the sweep in a raw KilledWorker traceback: now it is a row naming the failure, the other
    points' rows kept, exit 6. Dask gives a task up at the first death of its worker here (allowed-failures 0; 3
    by default: four workers die first), and every task on that worker with it: the point is the last and waits for
    the others' rows, so that it is alone in flight when it dies."""
    pytest.importorskip("distributed")  # its config defaults in place before the set below (restored after it)
    import dask

    from pinstab.bench import sweep

    out = tmp_path / "t.csv"

    def run_or_die(scene_name, point, fixed, parameters):  # sent to the workers by value (cloudpickle)
        if point["drift_limit"] == 6:
            deadline = time.monotonic() + 20  # the other points' rows written: none in flight with this one
            while rows_in(out) < 5 and time.monotonic() < deadline:
                time.sleep(0.02)
            os._exit(70)
        return run_point(scene_name, point, fixed, parameters)

    monkeypatch.setattr(sweep, "run_point", run_or_die)
    grid = ["sweep", "fourbar", "--grid", "drift_limit=1,2,3,4,5,6", "--param", "duration=0.05", "-o", str(out)]
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):  # the local cluster's scheduler: here
        code = main([*grid, "--quiet"])
    err = capsys.readouterr().err
    assert code == 6 and "Traceback" not in err, err
    assert f"1 of 6 points failed; their rows in {out} name the errors" in err
    rows = {row["drift_limit"]: row for row in table_rows(out)}
    assert sorted(rows) == [1, 2, 3, 4, 5, 6]
    assert all(rows[key]["error"] is None and rows[key]["t_end"] == pytest.approx(0.05) for key in range(1, 6))
    assert rows[6]["t_end"] is None and rows[6]["error"].startswith(
        "KilledWorker: every Dask worker that ran this point died (1 of them: a crash in compiled code"
    )


def test_a_lost_scheduler_is_a_named_error_and_the_table_kept(tmp_path, capsys, monkeypatch):
    """The scheduler killed while points are in flight (by the fourth point's run, on the worker): the sweep ends
    with a PinstabError naming the scheduler and the rows kept (exit 2, no traceback: Dask's client logs its failed
    reconnection with one), the rows written before it in the table, loadable."""
    from pinstab.bench import sweep

    dask = Path(sys.executable).with_name("dask")
    file = tmp_path / "scheduler.json"
    quiet = {"env": env(), "stderr": subprocess.DEVNULL, "start_new_session": True}
    command = [dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--scheduler-file", file, "--no-dashboard"]
    scheduler = subprocess.Popen(command, **quiet)
    command = [dask, "worker", "--scheduler-file", file, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"]
    worker = subprocess.Popen(command, cwd=tmp_path, **quiet)
    try:
        deadline = time.monotonic() + 30
        while not file.exists():
            assert time.monotonic() < deadline
            time.sleep(0.05)
        address, pid = json.loads(file.read_text())["address"], scheduler.pid

        def run_or_kill(scene_name, point, fixed, parameters):  # sent to the worker by value (cloudpickle)
            if point["drift_limit"] == 4:
                os.kill(pid, signal.SIGKILL)
            return run_point(scene_name, point, fixed, parameters)

        monkeypatch.setattr(sweep, "run_point", run_or_kill)
        out = tmp_path / "t.csv"
        grid = ["sweep", "fourbar", "--grid", "drift_limit=1,2,3,4,5,6", "--param", "duration=0.05", "-o", str(out)]
        code = main([*grid, "--scheduler", address, "--quiet"])
    finally:
        for process in (worker, scheduler):
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    rows = table_rows(out)
    assert f"pinstab sweep: error: sweep: the Dask scheduler {address} was lost (" in err
    assert f"); {len(rows)} new rows in {out}, resumed by a re-run\n" in err
    assert [row["drift_limit"] for row in rows] == [1, 2, 3][: len(rows)]
    assert all(row["error"] is None for row in rows)
