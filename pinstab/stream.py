"""Runs streamed to an HDF5 file as they proceed (``simulate(..., stream="run.h5")``, ``pinstab run --stream``).

The file holds plain datasets, one row per kept sample, readable by any HDF5 tool (h5py, h5dump, MATLAB,
pandas): :data:`SAMPLES` while the run proceeds, appended and flushed every :data:`BLOCK` samples or
:data:`FLUSH_PERIOD` seconds, whichever comes first, in HDF5's single-writer / multiple-reader mode (open it
with ``h5py.File(path, "r", swmr=True)`` while it runs; ``dataset.refresh()`` shows the rows flushed since),
and :data:`DERIVED` once the run has ended (computed from the samples in blocks, as a run kept in memory
computes them when first read). The run's
:class:`~pinstab.runinfo.RunInfo` is the root attribute ``info`` (JSON), its main fields also plain
attributes; ``complete`` says whether the run ended normally (finished, diverged or stopped, with its
derived series) or was cut short (interrupted, killed: the rows flushed so far, derived series empty).
Needs ``h5py`` (the ``stream`` extra: ``pip install pinstab[stream]``).

Written as :func:`pinstab.files.atomic_output` writes ``--save``'s files, a link at the target replaced, never
followed: the file is created as a temporary file in the target's folder (``.run.h5.pinstab-<pid>-<random>.h5``,
mkstemp's: never through a link), its datasets and attributes written and put in SWMR mode, and renamed onto the
target once its first rows are written and flushed. It is renamed then rather than when the run ends because a
stream is for runs that may not end as planned: from its first row on, the target is the run's own file, readable
while the run proceeds and holding every row flushed whatever ends the run, Ctrl-C, SIGTERM or ``kill -9`` included.
A run that fails before its first row is written (refused at its start) removes its temporary file and leaves the
target as it was, an earlier file there included (a run killed then leaves a temporary file, removed by the next
write to the target). An earlier file at the target is thus replaced once the run has rows, not when it ends. Its
end (the derived series, the final info) is written to the file at the target.

Read back (:func:`read_stream`, :func:`open_run_file`), a file its writer closed is opened as any HDF5 file; one
still being written or whose writer was killed (its superblock says so) in SWMR mode, with few attempts at a
damaged block (:data:`SWMR_READ_ATTEMPTS`). A truncated or damaged file, or an HDF5 file of something else, is a
PinstabError naming the file and what cannot be read.
"""

from __future__ import annotations

import ctypes
import functools
import json
import mmap
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from .errors import PinstabError
from .files import publish, temporary_output
from .runinfo import RunInfo

FORMAT = "pinstab-stream"  # the root attribute ``format``
VERSION = 1
BLOCK = 4096  # samples per HDF5 chunk, and per write and flush at most
FLUSH_PERIOD = 1.0  # [s] of wall time at most between two writes and flushes of a run's checked samples: a block
# takes 0.5 s on nfourbar N=40 but half a minute on the four-bar keeping a sample every 1000 steps, and a run killed
# (kill -9) keeps only the rows flushed; a write of part of a block and its flush cost 0.5 ms (5 ms at worst, measured
# over 60 writes), under 1% of the second between two
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
CHUNK_CACHE = 0  # bytes of HDF5's chunk cache: off, writes are blocks or, once a second, part of one (with h5py's
# default the resident memory grew by about a chunk per chunk written: 47 MiB over 10^6 rows of 9 columns, measured)
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
        self.path, self.temp = temporary_output(path, ".h5", "streamed run")
        self.file = None
        self.published = False  # renamed onto the target (by the first write of rows)
        self.size = 0
        try:  # the temporary file goes unless renamed: an error, Ctrl-C or SIGTERM while the layout is written
            try:
                self.file = h5py.File(self.temp, "w", libver="latest", rdcc_nbytes=CHUNK_CACHE)
            except OSError as exc:
                raise PinstabError(f"cannot write {path}: {exc}") from None
            self._create_layout(info, nq, nv, rows)
            self.file.swmr_mode = True  # no new datasets or attributes from here: readers may open it
        except BaseException:
            self.close()
            raise

    def _create_layout(self, info: RunInfo, nq: int, nv: int, rows: int) -> None:
        """The empty datasets of :data:`SAMPLES` and :data:`DERIVED` (``q``, ``v`` and ``multipliers`` of widths
        ``nq``, ``nv`` and ``rows``) and the root attributes."""
        widths = {"q": nq, "v": nv, "multipliers": rows}
        integers = ("step", "correction_iterations")
        for name, units in (SAMPLES | DERIVED).items():
            width = widths.get(name)
            shape, chunks = ((0,), (BLOCK,)) if width is None else ((0, width), (BLOCK, max(width, 1)))
            dataset = self.file.create_dataset(
                name,
                shape=shape,
                maxshape=(None, None) if width == 0 else (None, *shape[1:]),  # HDF5 chunks no fixed width of 0
                chunks=chunks,
                dtype=np.int64 if name in integers else np.float64,
            )
            dataset.attrs["units"] = units
        self.file.attrs.update(format=FORMAT, version=VERSION, complete=False, wall_time=float("nan"))
        write_info(self.file, info)

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
        if end and not self.published:  # the target is the run's file from its first row on
            publish(self.temp, self.path)
            self.published = True

    def close(self) -> None:
        """Close the file (what was written stays; :class:`StreamFile` adds the derived series); a file without
        rows, never renamed onto the target (a run that failed at its start), is removed, the target left as it
        was. Closing again does nothing."""
        if self.file is not None:
            self.file.close()
        if not self.published:
            Path(self.temp).unlink(missing_ok=True)


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

    def finish(self, summary: dict[str, Any] | None) -> None:
        """Write the summary figures (None: a run cut short) and close; the final info follows
        (:func:`rewrite_info`, which marks the file complete)."""
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


def rewrite_info(path: str | Path, info: RunInfo, wall_time: float, complete: bool) -> None:
    """Replace the run info (:func:`write_info`) and the wall time [s] of a finished run file, and say whether it is
    ``complete`` (its derived series written) in the same write: a kill before it leaves the file marked cut short."""
    with h5py_module().File(path, "r+") as file:
        write_info(file, info)
        file.attrs["wall_time"] = wall_time
        file.attrs["complete"] = complete


def sample_blocks(path: str | Path) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(t [s], q) of a run file's samples, :data:`BLOCK` at a time."""
    with open_run_file(path) as file:
        times, configurations = file["t"], file["q"]
        for start in range(0, min(len(times), len(configurations)), BLOCK):
            yield times[start : start + BLOCK], configurations[start : start + BLOCK]


def read_stream(path: str | Path) -> tuple[dict[str, np.ndarray], RunInfo, float, bool]:
    """(arrays by name, info, wall time [s], complete) of a run file; a run cut off before its derived series
    were written has them NaN. A file whose run still proceeds, or was killed, reads up to the last flushed row
    (:func:`open_run_file`).

    Raises:
        PinstabError: not an HDF5 file, a truncated or damaged one, or not a pinstab run file (naming what is
            missing or cannot be read).
    """
    with open_run_file(path) as file:
        with _reading(path, "the root attributes and the datasets' names"):
            attributes = dict(file.attrs)
            missing = [name for name in (*SAMPLES, *DERIVED) if name not in file]
        if attributes.get("format") != FORMAT or missing or "info" not in attributes:
            raise PinstabError(
                f"{path}: not a pinstab run file (format {attributes.get('format')!r}"
                + (f", no {', '.join(missing)})" if missing else ")")
            )
        info = RunInfo.from_json(attributes["info"], str(path))
        datasets = {}
        for name in (*SAMPLES, *DERIVED):
            with _reading(path, f"dataset {name!r}"):
                datasets[name] = np.asarray(file[name][()])
            if datasets[name].ndim == 0:
                raise PinstabError(f"{path}: dataset {name!r} holds a single value, not a row per sample")
        n = min(len(datasets[name]) for name in SAMPLES)  # a reader may see a block's t before its q
        arrays = {name: datasets[name][:n] for name in SAMPLES}
        for name in DERIVED:
            rows = datasets[name]
            if len(rows) < n:  # cut short before the derived series
                rows = np.full((n, *rows.shape[1:]), np.nan)
            arrays[name] = rows[:n]
        with _reading(path, "attributes 'wall_time' and 'complete'"):
            return arrays, info, float(attributes["wall_time"]), bool(attributes["complete"])


READ_ERRORS = (OSError, RuntimeError, KeyError, ValueError, TypeError)  # what h5py raises on a damaged file


@contextmanager
def _reading(path: str | Path, what: str) -> Iterator[None]:
    """Around a read of ``what``: h5py's errors on a damaged file become a PinstabError naming the file and what."""
    try:
        yield
    except READ_ERRORS as exc:
        raise PinstabError(f"{path}: a damaged HDF5 run file: {what} cannot be read ({exc})") from None


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
GLOBAL_HEAP = b"GCOL\x01\x00\x00\x00"  # a global heap collection's signature, version 1 and reserved bytes
BEING_WRITTEN = 0x01 | 0x04  # the superblock's file consistency flags: open for writing, for SWMR writing
SWMR_READ_ATTEMPTS = 20  # a SWMR reader retries a metadata read whose checksum fails (the writer may be amid a
# flush), backing off longer each time: HDF5's default of 100 attempts spent over 10 minutes on a killed stream whose
# root object header is damaged (over 100 s on one cut to 150 bytes), 20 fail on both in 10 to 13 ms (measured); a
# live reader that meets a block amid its flush fails and reads again (HDF5's own SWMR example uses 20)


@contextmanager
def open_run_file(path: str | Path) -> Iterator[Any]:
    """The HDF5 file ``path`` opened read-only (an ``h5py.File``): a file closed by its writer as usual, a file
    still being written or whose writer was killed (its superblock says so) in SWMR mode, which reads up to the
    last flushed row, with :data:`SWMR_READ_ATTEMPTS` attempts at each metadata read.

    Raises:
        PinstabError: the file is not HDF5, is shorter than its superblock declares (truncated), or HDF5 cannot
            open it (naming the file and HDF5's reason).
    """
    h5py = h5py_module()
    being_written = _superblock_check(path)
    try:
        if being_written:
            flags = h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ
            file = h5py.File(h5py.h5f.open(os.fsencode(path), flags, fapl=_swmr_access(h5py)))
        else:
            file = h5py.File(path, "r", locking=False, rdcc_nbytes=CHUNK_CACHE)
    except READ_ERRORS as exc:
        raise PinstabError(f"{path}: not a readable HDF5 run file ({exc})") from None
    with file:
        yield file


def _superblock_check(path: str | Path) -> bool:
    """Whether the HDF5 file ``path`` is being written (or its writer was killed), by its superblock's consistency
    flags (version 2 and later, as a stream's; False for earlier ones and a file without the signature at its start,
    left to HDF5's own checks); its global heaps checked (:func:`_check_global_heaps`).

    Raises:
        PinstabError: the file is shorter than the end of file its superblock declares, or a global heap is damaged.
    """
    try:
        with open(path, "rb") as handle:
            header = handle.read(64)
            size = os.fstat(handle.fileno()).st_size
            if not header.startswith(HDF5_SIGNATURE) or len(header) < 16:
                return False
            version, flags = header[8], header[11]
            widths = (header[9], header[10]) if version >= 2 else (header[13], header[14])  # addresses, lengths
            if widths[0] not in (2, 4, 8) or widths[1] not in (2, 4, 8):  # a damaged superblock: HDF5 names it
                return False
            if version >= 2:
                _check_size(path, header, size, widths[0])
            _check_global_heaps(path, handle, widths[1])
    except OSError as exc:
        raise PinstabError(f"{path}: cannot be read ({exc.strerror})") from None
    return version >= 2 and bool(flags & BEING_WRITTEN)


def _check_size(path: str | Path, header: bytes, size: int, width: int) -> None:
    """Refuse a file of ``size`` bytes shorter than the end its superblock (version 2 or later, ``header``, addresses
    of ``width`` bytes) declares."""
    fields = header[12 : 12 + 3 * width]  # base address, superblock extension address, end of file address
    if len(fields) < 3 * width:
        raise PinstabError(f"{path}: a truncated HDF5 file ({size} bytes, its superblock cut short)")
    base, _, end = (int.from_bytes(fields[k * width : (k + 1) * width], "little") for k in range(3))
    if size < base + end:
        raise PinstabError(
            f"{path}: a truncated or damaged HDF5 file: {size} bytes where its superblock declares {base + end} (a "
            "copy or a download cut short, or a full disk)"
        )


def _check_global_heaps(path: str | Path, handle: BinaryIO, width: int) -> None:
    """Walk the file's global heap collections (where HDF5 keeps variable-length strings: the attributes) object by
    object as HDF5 reads them, lengths of ``width`` bytes: the one structure of a file without a checksum, and a
    damaged object size can make HDF5 2.0's walk loop forever (found by damaging a stream's bytes: a free-space
    object of size 0). A collection is found by its 8-byte signature (numbers that spell it, the step 5 575 230 279
    or a float's bytes, would be taken for one); an object that would make no progress or run past its collection's
    end is refused.

    Raises:
        PinstabError: naming the byte at which the damaged collection starts.
    """
    header, entry = len(GLOBAL_HEAP) + width, 8 + width  # a collection's header, an object's header
    with mmap.mmap(handle.fileno(), 0, access=mmap.ACCESS_READ) as data:
        start = data.find(GLOBAL_HEAP)
        while start >= 0:
            end = start + int.from_bytes(data[start + len(GLOBAL_HEAP) : start + header], "little")
            damaged = f"{path}: a damaged HDF5 file: the global heap collection at byte {start} (attributes' strings)"
            if end > len(data):
                raise PinstabError(f"{damaged} runs past the file's end ({end} > {len(data)} bytes)")
            at = start + header
            while at + entry <= end:
                index = int.from_bytes(data[at : at + 2], "little")
                length = int.from_bytes(data[at + 8 : at + entry], "little")
                need = length if index == 0 else entry + -(-length // 8) * 8  # object 0: the free space, whole
                if need == 0:
                    raise PinstabError(f"{damaged} holds an empty free space at byte {at}")
                if at + need > end:
                    raise PinstabError(f"{damaged} holds an object of {length} bytes at byte {at}, past its end")
                at += need
            start = data.find(GLOBAL_HEAP, start + 1)


def _swmr_access(h5py: Any) -> Any:
    """A file access property list for a SWMR reader: no file locking (the writer holds the lock), no chunk cache,
    :data:`SWMR_READ_ATTEMPTS` attempts at a metadata read (set through the HDF5 library h5py loaded, found in the
    process's memory map; HDF5's default where it cannot be found)."""
    access = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    access.set_fclose_degree(h5py.h5f.CLOSE_STRONG)
    access.set_file_locking(False, True)
    metadata, slots, _, weight = access.get_cache()
    access.set_cache(metadata, slots, CHUNK_CACHE, weight)
    library = _hdf5_library()
    if library is not None:
        library.H5Pset_metadata_read_attempts(access.id, SWMR_READ_ATTEMPTS)
    return access


@functools.cache
def _hdf5_library() -> ctypes.CDLL | None:
    """The HDF5 library h5py loaded (its path in ``/proc/self/maps``), or None where it cannot be found."""
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "/libhdf5" in line and "libhdf5_hl" not in line}
    except OSError:
        return None
    for path in sorted(paths):
        library = ctypes.CDLL(path)
        if hasattr(library, "H5Pset_metadata_read_attempts"):
            library.H5Pset_metadata_read_attempts.argtypes = (ctypes.c_int64, ctypes.c_uint)
            return library
    return None
