"""A sweep's table, written a row at a time so that a killed sweep resumes: CSV (standard library) or Parquet
(pyarrow, the ``sweep`` extra).

The rows go to a CSV journal, each flushed when written: the ``.csv`` itself, or ``FILE.parquet.partial.csv``
beside a Parquet target, converted to ``FILE.parquet`` (atomically) when the sweep ends and then removed. On
opening, the points already in the journal (or in an existing Parquet file) are :attr:`SweepTable.done`; a last
line cut short by a kill is dropped. A file that is not a table (not UTF-8 text, a malformed CSV, a corrupt
Parquet file) is a named error.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from ..errors import PinstabError
from ..files import atomic_output, check_output

SUFFIXES = (".csv", ".parquet")
JOURNAL = ".partial.csv"  # appended to a Parquet target's name
SHOWN = 300  # characters of a foreign header an error quotes
CHUNK = 1 << 20  # [bytes] read at a time when counting rows
TEXT = {"encoding": "utf-8"}  # a table's text, whatever the locale
MAX_LINE = 1 << 20  # [bytes] a row: its ~27 cells take hundreds, an error message's a few thousand at most


def point_key(values: Iterable[Any]) -> tuple[str, ...]:
    """A point's grid values as text, numbers as floats: ``2``, ``2.0``, the CSV cell ``"2"`` and a Parquet
    double 2.0 give one key."""
    cells = (_cell(value) if isinstance(value, str) else value for value in values)
    return tuple(repr(float(v)) if isinstance(v, int | float) and not isinstance(v, bool) else str(v) for v in cells)


def check_table(path: str | Path) -> Path:
    """Refuse a table target before any work: a suffix other than ``.csv``/``.parquet``, Parquet without
    pyarrow (naming the extra), a folder that cannot take it (:func:`~pinstab.files.check_output`)."""
    path = Path(path)
    if path.suffix not in SUFFIXES:
        raise PinstabError(f"sweep table {str(path)!r}: give a file ending in {' or '.join(SUFFIXES)}")
    if path.suffix == ".parquet":
        _pyarrow()
    return check_output(path, path.suffix, "sweep table")


def _pyarrow() -> Any:
    try:
        import pyarrow
        import pyarrow.csv
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        raise PinstabError("Parquet tables need pyarrow: pip install 'pinstab[sweep]' (or give a .csv)") from None
    return pyarrow


class SweepTable:
    """The rows of a sweep over ``columns`` whose first ``keys`` name the point; a context manager.

    Attributes:
        path: the target. journal: the CSV the rows are appended to. done: the keys (:func:`point_key`) of the
            points already in it. failed: those of them whose row holds an error.

    Raises:
        PinstabError: the target refused (:func:`check_table`), or a table of another sweep (other columns).
    """

    def __init__(self, path: str | Path, columns: list[str], keys: int) -> None:
        self.path = check_table(path)
        self.columns, self.keys = columns, keys
        self.parquet = self.path.suffix == ".parquet"
        self.journal = self.path.with_name(self.path.name + JOURNAL) if self.parquet else self.path
        if self.parquet and self.path.exists() and not self.journal.exists():
            table = _parquet_table(self.path)
            _check_columns(self.path, table.column_names, columns)
            self._write_journal(table.to_pylist())
        self.done: set[tuple[str, ...]] = set()
        self.failed: set[tuple[str, ...]] = set()
        for row in read_rows(self.journal, columns) if self.journal.exists() else ():
            key = point_key(row[name] for name in columns[:keys])
            self.done.add(key)
            if row["error"]:
                self.failed.add(key)
        self._handle = None

    def __enter__(self) -> SweepTable:
        new = not self.journal.exists() or self.journal.stat().st_size == 0
        self._handle = open(self.journal, "a", newline="", **TEXT)  # noqa: SIM115 - closed in __exit__
        self._writer = csv.DictWriter(self._handle, fieldnames=self.columns)
        if new:
            self._writer.writeheader()
            self._handle.flush()
        return self

    def append(self, row: dict[str, Any]) -> None:
        """Write one point's row and flush it (a kill after this keeps it)."""
        self._writer.writerow(row)
        self._handle.flush()

    def __exit__(self, kind, error, traceback) -> None:
        self._handle.close()
        if self.parquet and kind is None:
            pyarrow = _pyarrow()
            table = pyarrow.csv.read_csv(self.journal)
            with atomic_output(self.path, ".parquet", "sweep table") as temp:
                pyarrow.parquet.write_table(table, temp)
            os.remove(self.journal)

    def _write_journal(self, rows: list[dict[str, Any]]) -> None:
        """The journal of a Parquet table's ``rows``, written whole or not at all (a kill keeps the Parquet file's)."""
        with atomic_output(self.journal, ".csv", "sweep journal") as temp:
            with open(temp, "w", newline="", **TEXT) as handle:
                writer = csv.DictWriter(handle, fieldnames=self.columns)
                writer.writeheader()
                writer.writerows(rows)


def read_rows(path: str | Path, columns: list[str] | None = None) -> Iterator[dict[str, str]]:
    """The rows of a sweep's CSV (the journal of a Parquet table too) as text, one at a time; a last line cut short
    by a kill is dropped (and cut from the file).

    Args:
        path: the CSV. columns: the columns it must have (None: any).

    Raises:
        PinstabError: not a table: a line not UTF-8 text, with a NUL byte or too long (:class:`_Lines`), a cell
            beyond the csv module's field limit, another number of cells than the header, no complete header; or
            other columns than ``columns`` (a table of another sweep). Each names the file and the line. The file
            is then left as it is.
    """
    path = Path(path)
    lines = _Lines(path)
    reader = csv.reader(lines)
    try:
        header = next(reader, None)
        if header is None:
            if lines.cut is not None:
                raise _not_a_table(path, 1, "no complete header line")
            return
        if columns is not None:
            _check_columns(path, header, columns)
        for cells in reader:
            if len(cells) != len(header):
                raise _not_a_table(path, lines.count, f"{len(cells)} cell(s), the header {len(header)}")
            yield dict(zip(header, cells, strict=True))
    except csv.Error as exc:
        raise _not_a_table(path, lines.count, str(exc)) from None
    if lines.cut is not None:
        os.truncate(path, lines.cut)


class _Lines:
    """The complete lines of a file as text, one at a time (for ``csv.reader``): a last line without its newline
    (cut short by a kill) left out, its offset [bytes] in :attr:`cut` once the lines are read.

    Raises:
        PinstabError: a line that is not UTF-8 text, holds a NUL byte or is longer than :data:`MAX_LINE` bytes.
    """

    def __init__(self, path: Path) -> None:
        self.path, self.count, self.cut = path, 0, None

    def __iter__(self) -> Iterator[str]:
        with open(self.path, "rb") as handle:
            offset = 0
            while line := handle.readline(MAX_LINE + 1):
                self.count += 1
                if not line.endswith(b"\n"):
                    if len(line) > MAX_LINE:
                        raise _not_a_table(self.path, self.count, f"longer than {MAX_LINE:,} bytes")
                    self.cut = offset
                    return
                if b"\0" in line:
                    raise _not_a_table(self.path, self.count, "a NUL byte (binary data)")
                try:
                    yield line.decode("utf-8")
                except UnicodeDecodeError as exc:
                    raise _not_a_table(self.path, self.count, f"not UTF-8 text ({exc.reason})") from None
                offset += len(line)


def _not_a_table(path: Path, line: int, reason: str) -> PinstabError:
    """The error for a file that is not a sweep table, at ``line`` (counted from 1) of it."""
    return PinstabError(f"{path} is not a sweep table: line {line}: {reason}; give another --out or remove it")


def existing_rows(path: str | Path) -> int:
    """The rows already in a sweep's table [count], without reading them: its journal's lines less the header,
    else a Parquet file's row count (its metadata); 0 for none."""
    path = Path(path)
    journal = path.with_name(path.name + JOURNAL) if path.suffix == ".parquet" else path
    if journal.exists():
        with open(journal, "rb") as handle:
            lines = sum(block.count(b"\n") for block in iter(lambda: handle.read(CHUNK), b""))
        return max(lines - 1, 0)
    if path.exists():
        return _parquet(path, lambda parquet: parquet.read_metadata(path).num_rows)
    return 0


def _check_columns(path: Path, found: list[str], columns: list[str]) -> None:
    """Refuse a table whose columns are not this sweep's.

    Raises:
        PinstabError: naming the file and the columns it holds.
    """
    if list(found) != columns:
        held = ", ".join(found)
        shown = held if held.isprintable() and len(held) <= SHOWN else f"{held[:SHOWN]!r}..."
        raise PinstabError(f"{path} holds another sweep's table (columns {shown}); give another --out or remove it")


def table_rows(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a sweep's table, CSV or Parquet (the journal of one cut short, when it is there: it holds the
    rows so far), with numbers, booleans and None (an empty cell) as such.

    Raises:
        PinstabError: not a table (:func:`read_rows`, or not a Parquet file).
    """
    path = Path(path)
    journal = path.with_name(path.name + JOURNAL)
    if path.suffix == ".parquet" and not journal.exists():
        return _parquet_table(path).to_pylist()
    rows = read_rows(journal if path.suffix == ".parquet" else path)
    return [{name: _cell(text) for name, text in row.items()} for row in rows]


def _parquet_table(path: Path) -> Any:
    """A Parquet file's table (pyarrow).

    Raises:
        PinstabError: not a Parquet file, naming it and pyarrow's reason.
    """
    return _parquet(path, lambda parquet: parquet.read_table(path))


def _parquet(path: Path, read: Any) -> Any:
    """``read(pyarrow.parquet)``, pyarrow's error on a file that is not Parquet named as a PinstabError."""
    pyarrow = _pyarrow()
    try:
        return read(pyarrow.parquet)
    except (pyarrow.ArrowException, OSError) as exc:
        raise PinstabError(
            f"{path} is not a sweep table: not a Parquet file ({exc}); give another --out or remove it"
        ) from None


def _cell(text: str) -> Any:
    if text in ("", "True", "False"):
        return None if text == "" else text == "True"
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text
