"""A stream's file at the start and at the end of its run (issue 34, the fuzzer's stream defects).

A run refused at its start (exit 2) left its ``--stream`` file holding no sample (the file was renamed onto the
target before the first row): now the target becomes the run's file with its first rows, and a run that fails before
them removes its temporary file and leaves the target as it was. A run whose last write came before its end (a write
once a second of wall time, FLUSH_PERIOD, that covered every sample) had its last row rewritten from a stale slot of
the window, t = 0 (Trajectory.load: "the sample times 't' must increase"; pinstab/integration/records.py).
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np
import pytest

from pinstab.cli import main
from pinstab.errors import CutShortWarning, SolverError
from pinstab.simulate import simulate
from pinstab.stream import StreamWriter
from pinstab.trajectory import Trajectory

pytest.importorskip("h5py")
loop_module = importlib.import_module("pinstab.simulate.loop")  # pinstab.simulate's ``simulate`` hides the module

PREVIOUS = b"the previous run"


def _refuse_at_start(*args, **kwargs) -> None:
    raise SolverError("contacts c0 at t = 0 s: the mass matrix is singular (a stand-in for a failure at the start)")


@pytest.mark.parametrize(
    ("scene", "contacts", "target"),
    [
        ("bouncing-ball", "event", "pinstab.integration.events.EventLoop.start"),
        ("fourbar", "held", "pinstab.system.ConstrainedSystem.audit"),
    ],
)
def test_a_run_refused_at_its_start_leaves_the_target_as_it_was(tmp_path, capsys, monkeypatch, scene, contacts, target):
    """The run fails after its stream's file is set up, before its first row (the event path's first modes, the
    held path's first solve): exit 2, the file at the target keeps its bytes, no temporary file is left."""
    path = tmp_path / "run.h5"
    path.write_bytes(PREVIOUS)
    monkeypatch.setattr(target, _refuse_at_start)
    argv = ["run", scene, "--contacts", contacts, "--duration", "0.05", "--quiet", "--stream", str(path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "the mass matrix is singular" in err and "Traceback" not in err
    assert path.read_bytes() == PREVIOUS and [p.name for p in tmp_path.iterdir()] == ["run.h5"]
    path.unlink()
    assert main(argv) == 2 and list(tmp_path.iterdir()) == []  # no target before: none after


def test_the_target_is_replaced_by_the_first_rows(tmp_path):
    """Until its first write the writer's file is a temporary one beside the target; the write renames it."""
    path = tmp_path / "run.h5"
    path.write_bytes(PREVIOUS)
    run = simulate("fourbar", duration=0.002)
    writer = StreamWriter(path, run.info, nq=3, nv=3, rows=2)
    try:
        assert path.read_bytes() == PREVIOUS and len(list(tmp_path.iterdir())) == 2
        writer.write(0, run.t, np.arange(3), run.q, run.v, np.zeros(3, dtype=int))
        assert [p.name for p in tmp_path.iterdir()] == ["run.h5"]
    finally:
        writer.close()
    with pytest.warns(CutShortWarning, match="cut short at t = 0.002 s"):  # never completed: as kill -9 leaves it
        assert np.array_equal(Trajectory.load(path).q, run.q)


@pytest.mark.parametrize("contacts", ["held", "event", "stepping"])
def test_a_run_whose_last_write_covered_every_sample_ends_on_its_last_row(tmp_path, monkeypatch, contacts):
    """Every check writes (FLUSH_PERIOD 0, as a run whose last chunk took over a second): the file holds the same
    rows as the run kept in memory, its last at the duration (it read t = 0: the window moved back over rows it no
    longer held)."""
    monkeypatch.setattr(loop_module, "FLUSH_PERIOD", 0.0)
    scene = "fourbar" if contacts == "held" else "bouncing-ball"
    options = {} if contacts == "held" else {"contacts": contacts}
    path = tmp_path / "run.h5"
    streamed = simulate(scene, duration=0.25, stream=path, **options)
    kept = simulate(scene, duration=0.25, **options)
    assert streamed.info.t_end == kept.info.t_end == 0.25 and streamed.info.steps == kept.info.steps == 250
    loaded = Trajectory.load(path)
    assert np.array_equal(loaded.t, kept.t) and np.array_equal(loaded.q, kept.q) and np.array_equal(loaded.v, kept.v)


def test_a_limit_rerun_refused_at_its_start_leaves_no_held_run(tmp_path, capsys, monkeypatch):
    """A joint started on its limit moving into it: the held path's run (streamed, complete) leaves the limit, the
    event path runs again from the start to the same file and fails there: the held run's file, which passed the
    limit, is not left at the target as the run's."""
    sys.path.insert(0, str(Path(__file__).parent))
    from fuzzing import toml_document
    from test_fuzz_tables import limited_chain_urdf

    scene = tmp_path / "limit.toml"
    chain = {"urdf_text": limited_chain_urdf([(0.0, 1.0)])}
    start = {"q": {"j0": 1.0}, "v": {"j0": 0.2}}
    scene.write_text(toml_document({"gravity": [0.0, -9.81, 0.0], "robot": chain, "initial": start}), "utf-8")
    path = tmp_path / "run.h5"
    monkeypatch.setattr("pinstab.integration.events.EventLoop.start", _refuse_at_start)
    assert main(["run", str(scene), "--duration", "0.05", "--quiet", "--stream", str(path)]) == 2
    assert "the mass matrix is singular" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["limit.toml"]
