"""Runs streamed to an HDF5 file as they proceed (``simulate(..., stream="run.h5")``, ``pinstab run --stream``).

The file holds plain datasets, one row per kept sample, readable by any HDF5 tool (h5py, h5dump, MATLAB,
pandas): :data:`SAMPLES` while the run proceeds, appended and flushed every :data:`BLOCK` samples in HDF5's
single-writer / multiple-reader mode (open it with ``h5py.File(path, "r", swmr=True)`` while it runs;
``dataset.refresh()`` shows the rows flushed since), and :data:`DERIVED` once the run has ended (computed
from the samples in blocks, as a run kept in memory computes them when first read). The run's
:class:`~pinstab.runinfo.RunInfo` is the root attribute ``info`` (JSON), its main fields also plain
attributes; ``complete`` says whether the run ended normally (finished, diverged or stopped, with its
derived series) or was cut off (interrupted, killed: the rows flushed so far, derived series empty).
Needs ``h5py`` (the ``stream`` extra: ``pip install pinstab[stream]``).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from .errors import PinstabError
from .runinfo import RunInfo

FORMAT = "pinstab-stream"  # the root attribute ``format``
VERSION = 1
BLOCK = 4096  # samples per HDF5 chunk, per write and per flush
SAMPLES = {  # written while the run proceeds: name -> units
    "t": "s",
    "step": "-",
    "q": "rad or m per coordinate (Pinocchio's configuration vector)",
    "v": "rad/s or m/s per coordinate (Pinocchio's tangent velocity)",
    "correction_iterations": "-",
}
DERIVED = {  # written when the run has ended: name -> units
    "multipliers": "N or N m per row (info.constraint_rows; frames info.force_frames)",
    "position_drift": "m or rad",
    "velocity_drift": "m/s or rad/s",
    "energy": "J",
    "spectral_radius": "-",
}
CHUNK_CACHE = 0  # bytes of HDF5's chunk cache: off, writes are whole blocks (with h5py's default the resident
# memory grew by about a chunk per chunk written: 47 MiB over 10^6 rows of 9 columns, measured)
INFO_ATTRIBUTES = ("scene", "method", "integrator", "solver", "dt", "record_every", "path")


def h5py_module():
    """The ``h5py`` module.

    Raises:
        PinstabError: it is not installed (naming the extra that brings it).
    """
    try:
        import h5py
    except ImportError:
        raise PinstabError(
            "streaming a run to HDF5 needs h5py, which is not installed: pip install 'pinstab[stream]' (or h5py)"
        ) from None
    return h5py


def is_stream_file(path: str | Path) -> bool:
    """Whether ``path`` names an HDF5 run file (by its suffix: ``.h5``, ``.hdf5``)."""
    return Path(path).suffix.lower() in (".h5", ".hdf5")


class StreamWriter:
    """Appends a run's samples to an HDF5 file (created, or replaced) as they are kept.

    Args:
        path: the file. info: the run's info so far. nq, nv, rows: sizes of q, v and the multipliers.
    """

    def __init__(self, path: str | Path, info: RunInfo, nq: int, nv: int, rows: int) -> None:
        h5py = h5py_module()
        self.path = Path(path)
        try:
            self.file = h5py.File(self.path, "w", libver="latest", rdcc_nbytes=CHUNK_CACHE)
        except OSError as exc:
            raise PinstabError(f"cannot write {path}: {exc}") from None
        widths = {"q": nq, "v": nv, "multipliers": rows}
        integers = ("step", "correction_iterations")
        for name, units in (SAMPLES | DERIVED).items():
            width = widths.get(name)
            shape, chunks = ((0,), (BLOCK,)) if width is None else ((0, width), (BLOCK, max(width, 1)))
            dataset = self.file.create_dataset(
                name,
                shape=shape,
                maxshape=(None, *shape[1:]),
                chunks=chunks,
                dtype=np.int64 if name in integers else np.float64,
            )
            dataset.attrs["units"] = units
        self.file.attrs.update(format=FORMAT, version=VERSION, complete=False, wall_time=float("nan"))
        write_info(self.file, info)
        self.file.swmr_mode = True  # no new datasets or attributes from here: readers may open it
        self.size = 0

    def write(
        self, start: int, t: np.ndarray, steps: np.ndarray, q: np.ndarray, v: np.ndarray, corrections: np.ndarray
    ) -> None:
        """Write the samples ``start`` .. ``start + len(t) - 1`` (replacing any from ``start`` on) and flush."""
        end = start + len(t)
        for name, rows in (("t", t), ("step", steps), ("q", q), ("v", v), ("correction_iterations", corrections)):
            dataset = self.file[name]
            dataset.resize(end, axis=0)
            dataset[start:end] = rows
        self.size = end
        self.file.flush()

    def close(self) -> None:
        """Close the file (what was written stays; :func:`complete` adds the derived series)."""
        self.file.close()


class StreamFile:
    """A run file reopened after its run to add the derived series and the final info (not a SWMR writer).

    Args:
        path: the file written by :class:`StreamWriter`.
    """

    def __init__(self, path: str | Path) -> None:
        self.file = h5py_module().File(path, "r+", rdcc_nbytes=CHUNK_CACHE)
        self.size = len(self.file["t"])

    def blocks(self) -> Iterator[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
        """(first row, t, q, v) of each block of :data:`BLOCK` samples, in order."""
        for start in range(0, self.size, BLOCK):
            stop = min(start + BLOCK, self.size)
            yield start, self.file["t"][start:stop], self.file["q"][start:stop], self.file["v"][start:stop]

    def write_series(self, start: int, series: dict[str, np.ndarray]) -> None:
        """Write derived series (:data:`DERIVED` names) from row ``start``."""
        for name, rows in series.items():
            dataset = self.file[name]
            dataset.resize(max(len(dataset), start + len(rows)), axis=0)
            dataset[start : start + len(rows)] = rows

    def finish(self, info: RunInfo, wall_time: float, summary: dict[str, Any] | None) -> None:
        """Write the final info, the wall time [s] and the summary figures (None: a run cut off); close."""
        write_info(self.file, info)
        self.file.attrs["wall_time"] = wall_time
        self.file.attrs["complete"] = summary is not None
        if summary is not None:
            self.file.attrs["summary"] = json.dumps(summary)
        self.file.close()


def write_info(file, info: RunInfo) -> None:
    """The run info as the attribute ``info`` (JSON) and its main fields as plain attributes."""
    file.attrs["info"] = json.dumps(info.to_dict())
    for name in INFO_ATTRIBUTES:
        file.attrs[name] = getattr(info, name)
    file.attrs["parameters"] = json.dumps(info.parameters)
    file.attrs["scene_parameters"] = json.dumps(info.scene_parameters)


def rewrite_info(path: str | Path, info: RunInfo, wall_time: float) -> None:
    """Replace the run info (:func:`write_info`) and the wall time [s] of a finished run file."""
    with h5py_module().File(path, "r+") as file:
        write_info(file, info)
        file.attrs["wall_time"] = wall_time


def sample_blocks(path: str | Path) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(t [s], q) of a run file's samples, :data:`BLOCK` at a time."""
    with h5py_module().File(path, "r", swmr=True, locking=False, rdcc_nbytes=CHUNK_CACHE) as file:
        times, configurations = file["t"], file["q"]
        for start in range(0, min(len(times), len(configurations)), BLOCK):
            yield times[start : start + BLOCK], configurations[start : start + BLOCK]


def read_stream(path: str | Path) -> tuple[dict[str, np.ndarray], RunInfo, float, bool]:
    """(arrays by name, info, wall time [s], complete) of a run file; a run cut off before its derived series
    were written has them NaN. Opened read-only in SWMR mode: a file whose run still proceeds reads up to the
    last flushed block.

    Raises:
        PinstabError: not an HDF5 file, or not a pinstab run file (naming what is missing).
    """
    h5py = h5py_module()
    try:
        file = h5py.File(path, "r", swmr=True, locking=False)
    except OSError as exc:
        raise PinstabError(f"{path}: not a readable HDF5 run file ({exc})") from None
    with file:
        missing = [name for name in (*SAMPLES, *DERIVED) if name not in file]
        if file.attrs.get("format") != FORMAT or missing or "info" not in file.attrs:
            raise PinstabError(
                f"{path}: not a pinstab run file (format {file.attrs.get('format')!r}"
                + (f", no {', '.join(missing)})" if missing else ")")
            )
        info = RunInfo.from_dict(json.loads(file.attrs["info"]))
        n = min(len(file[name]) for name in SAMPLES)  # a reader may see a block's t before its q
        arrays = {name: file[name][:n] for name in SAMPLES}
        for name in DERIVED:
            rows = file[name][()]
            if len(rows) < n:  # cut off before the derived series
                rows = np.full((n, *rows.shape[1:]), np.nan)
            arrays[name] = rows[:n]
        return arrays, info, float(file.attrs["wall_time"]), bool(file.attrs["complete"])
