"""Property-based fuzzing of ``pinstab sweep``'s grids (issue 34, item 6): ``--grid NAME=V1,V2,...`` strings with
names drawn from the scene's parameters, the run options and typos, values from their physical ranges, beyond them,
of the wrong type or malformed; ``--param`` values; the table's path absent, an existing file or a symbolic link.

The property: a sweep refused before any work (exit 2) names the grid or value at fault and writes no table (an
existing file or a link's target keeps its content); a sweep that runs (exit 0, or 6 when points failed) has a row
per point, finite figures, and failed rows only for what happens during a run (a divergence, contacts without a
solution), never for a value ``pinstab run`` refuses, which the sweep must refuse up front. Never a traceback or a
hang. Points run on a local Dask cluster of one worker process started here.

The number of examples comes from the Hypothesis profile (tests/conftest.py, :func:`~fuzzing.examples`).
"""

from __future__ import annotations

import contextlib
import csv
import json
import logging
import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fuzzing import (
    OUTPUT_STATES,
    PRECIOUS,
    Hang,
    Outcome,
    assert_not_lost,
    cli,
    examples,
    prepare_output,
    report,
    time_limit,
    toml_value,
)
from hypothesis import given
from hypothesis import strategies as st

from pinstab.bench.sweep_grid import RUN_OPTIONS
from pinstab.generators import GENERATOR_PARAMETERS

SCENES = ("bouncing-ball", "incline", "painleve-rod", "pinch", "fourbar")  # runs of 10 ms take milliseconds
DURATION = 0.01  # [s] each point's run, unless the grid sweeps it
# run failures a point's row may hold: what happens during a run, which no check before it can foresee
RUN_FAILURES = (
    "DivergenceError",
    "StepTooLargeError",
    "StiffStepError",
    "ProjectionError",
    "ContactInfeasibleError",
    "GraspLostError",
    "PainleveError",
    "ContactSolveError",
    "SolverError",
    "ServoInfeasibleError",
)
HOSTILE = [0, -1, -1.0, 0.0, 1e-300, 1e308, -1e308, math.nan, math.inf, -math.inf, 10**30, True, "abc", "rk4", ""]

# the values a name takes: the physical ones, bounded to runs of milliseconds (a second of pinch at dt = 1e-6 is a
# legitimate hour-long sweep, not what the fuzzer looks for), and the run options' named choices
PHYSICAL: dict[str, st.SearchStrategy] = {
    "dt": st.sampled_from([1e-3, 5e-4, 2e-3]),
    "duration": st.sampled_from([0.002, 0.005, 0.01]),
    "record_every": st.integers(1, 5),
    "rtol": st.sampled_from([1e-6, 1e-8]),
    "atol": st.sampled_from([1e-6, 1e-8]),
    "drift_limit": st.sampled_from([0.1, 1.0, 10.0]),
    "method": st.sampled_from(["baumgarte", "none", "projection", "post", "mukharlyamov", "pinocchio", "euler"]),
    "integrator": st.sampled_from(["rk4", "euler", "heun", "dopri5", "dop853", "semi-implicit-euler", "ode45"]),
    "solver": st.sampled_from(["dense", "proxsuite", "pinocchio", "lapack"]),
    "contacts": st.sampled_from(["event", "stepping", "held", "soft"]),
    "kp": st.sampled_from([1.0, 100.0, 1e4]),
    "kd": st.sampled_from([0.0, 20.0, 200.0]),
    "mu": st.floats(0.0, 10.0, allow_nan=False),
    "theta": st.floats(0.0, 1.5, allow_nan=False),
    "restitution": st.floats(0.0, 1.0, allow_nan=False),
    "height": st.floats(0.0, 0.05, allow_nan=False),
    "squeeze": st.floats(0.0, 5.0, allow_nan=False),
    "mass": st.floats(0.01, 1.0, allow_nan=False),
    "v_down": st.floats(-2.0, 2.0, allow_nan=False),
    "v_across": st.floats(-2.0, 2.0, allow_nan=False),
}
WORK = {"dt", "duration", "record_every", "rtol", "atol"}  # names whose hostile values must be refused, not run


def names_for(draw: st.DrawFn, scene: str) -> st.SearchStrategy[str]:
    """A name a sweep of the scene takes (mostly its parameters and the common run options), or one it does not."""
    generator = scene if scene in GENERATOR_PARAMETERS else ""
    common = [*GENERATOR_PARAMETERS.get(generator, {}), "dt", "duration", "method", "integrator", "contacts"]
    return draw(st.sampled_from(common) | st.sampled_from([*RUN_OPTIONS, "N", "Mu", "d t", "x", "", "dt=1"]))


@st.composite
def grid_values(draw: st.DrawFn, name: str) -> list[str]:
    """1 to 3 values of ``name`` as text: physical, hostile (a tiny dt, a huge duration...), or malformed (one time in
    twenty, a value given twice)."""
    values: list[str] = []
    for _ in range(draw(st.integers(1, 3))):
        if draw(st.integers(0, 5)) == 0 or name not in PHYSICAL:
            choice = draw(st.sampled_from(HOSTILE) | st.sampled_from(["1,", " ", '"x"', "[1]", "{}", "1e999", "0x1"]))
            values.append(choice if isinstance(choice, str) else toml_value(choice))
        else:
            values.append(toml_value(draw(PHYSICAL[name])))
    if draw(st.integers(0, 19)):
        values = list(dict.fromkeys(values))
    return values


@st.composite
def sweeps(draw: st.DrawFn) -> tuple[str, list[str], list[str]]:
    """A scene, its ``--grid`` arguments (one or two) and its ``--param`` arguments."""
    scene = draw(st.sampled_from(SCENES))
    grids = []
    for _ in range(draw(st.integers(1, 2))):
        name = names_for(draw, scene)
        separator = "=" if draw(st.integers(0, 9)) else draw(st.sampled_from([":", "=="]))
        grids.append(f"{name}{separator}{','.join(draw(grid_values(name)))}")
    params = [] if any(grid.startswith("duration=") for grid in grids) else [f"duration={DURATION}"]
    if draw(st.integers(0, 4)) == 0:
        name = names_for(draw, scene)
        params.append(f"{name}={draw(grid_values(name))[0]}")
    return scene, grids, params


@pytest.fixture(scope="module")
def scheduler() -> Iterator[Any]:
    """A client of a local Dask cluster of one worker process (one thread), which an example that hangs restarts:
    its point would keep the worker from the next examples' points."""
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=":0", silence_logs=logging.CRITICAL)
    with cluster, Client(cluster) as client:
        yield client


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz-sweeps")


def rows_of(path: Path) -> list[dict[str, str]]:
    """A CSV sweep table's rows."""
    with path.open(newline="") as file:
        return list(csv.DictReader(file))


def assert_rows(rows: list[dict[str, str]]) -> None:
    """Every row: finite figures; an error only from what happens during a run."""
    for row in rows:
        error = row.get("error", "")
        if error:
            kind = error.split(":", 1)[0]
            assert kind in RUN_FAILURES, f"a point failed with what run refuses before it starts: {error}"
            continue
        for key, value in row.items():
            if re.fullmatch(r"[-+]?(nan|inf|infinity)", value.strip(), re.IGNORECASE):
                raise AssertionError(f"column {key} = {value} in a row without an error: {row}")


def check_sweep(
    scene: str, grids: list[str], params: list[str], output: str, folder: Path, scheduler: Any, most: int | None = None
) -> None:
    """``pinstab sweep`` in process (``--max-points`` when ``most`` is given): refused by name with no table
    written, or a table of the points, which the same sweep run again resumes with nothing left to run."""
    table = folder / "sweep.csv"
    precious = prepare_output(table, output)
    argv = ["sweep", scene, *[f"--grid={grid}" for grid in grids], *[f"--param={param}" for param in params]]
    argv += ["-o", str(table), "--scheduler", scheduler.scheduler.address, "--quiet", "--json"]
    argv += [] if most is None else ["--max-points", str(most)]
    with restarted_on_hang(scheduler):
        outcome = cli(argv)
    report(f"exit {outcome.code}: {outcome.message or outcome.err[-300:]}", f"exit {outcome.code}")
    assert outcome.code in (0, 2, 6), outcome
    assert_not_lost(table, precious, output, rows_of)
    if outcome.code == 2:
        assert_named(outcome, [*grids, *params, table.name])
        if output == "absent":
            assert not table.exists(), "a refused sweep wrote its table"
        return
    if output != "absent" and table.read_text() == PRECIOUS:
        raise AssertionError(f"a sweep ran (exit {outcome.code}) and left {table} as it was")
    rows = rows_of(table)
    assert_rows(rows)
    result = json.loads(outcome.out)
    assert len(rows) == result["points"], f"{len(rows)} rows for {result['points']} points"
    with restarted_on_hang(scheduler):
        again = cli(argv)
    assert again.code == outcome.code, f"the sweep resumed exits {again.code}, not {outcome.code}: {again}"
    assert json.loads(again.out)["ran"] == 0 and rows_of(table) == rows, "a finished sweep ran points again"


@contextlib.contextmanager
def restarted_on_hang(client: Any) -> Iterator[None]:
    """:func:`~fuzzing.time_limit`, the cluster's worker restarted when it expires."""
    try:
        with time_limit():
            yield
    except Hang:
        client.restart()
        raise


def assert_named(outcome: Outcome, items: list[str]) -> None:
    """A refusal names a grid's or a param's name or one of their values (``NAME=V1,V2``), or the table."""
    words = {"--grid", "--param", "--max-points", "points"}
    for item in items:
        name, _, values = item.partition("=")
        words |= {name.strip(), *(value.strip() for value in values.split(",") if value.strip())}
    words.discard("")
    assert any(word in outcome.message for word in words), f"names none of {sorted(words)}: {outcome.message}"


@examples(ci=150)
@given(
    sweep=sweeps(),
    output=st.sampled_from(OUTPUT_STATES) | st.just("absent"),
    most=st.none() | st.none() | st.sampled_from([0, 1, 2, 10**6]),
)
def test_sweep_grids_refused_by_name_or_run(
    sweep: tuple[str, list[str], list[str]], output: str, most: int | None, folder: Path, scheduler: Any
) -> None:
    check_sweep(*sweep, output, folder, scheduler, most)
