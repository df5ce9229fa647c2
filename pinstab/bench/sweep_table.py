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
CHUNK = 1 << 20  # [bytes] read at a time when counting rows or looking for a cut last line


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
        self._handle = open(self.journal, "a", newline="")  # noqa: SIM115 - closed in __exit__
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
        with open(self.journal, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=self.columns)
            writer.writeheader()
            writer.writerows(rows)


def read_rows(path: str | Path, columns: list[str] | None = None) -> Iterator[dict[str, str]]:
    """The rows of a sweep's CSV (the journal of a Parquet table too) as text, one at a time; a last line cut short
    by a kill is dropped (and cut from the file).

    Args:
        path: the CSV. columns: the columns it must have (None: any).

    Raises:
        PinstabError: not a table: not UTF-8 text, a malformed line (a NUL byte, an unclosed quote, a cell beyond
            the csv module's field limit, another number of cells than the header); or other columns than
            ``columns`` (a table of another sweep). Each names the file and the line.
    """
    path = Path(path)
    _drop_cut_line(path)
    reader = None
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            reader = csv.reader(handle)
            header = next(reader, None)
            if header is None:
                return
            if columns is not None:
                _check_columns(path, header, columns)
            for cells in reader:
                if len(cells) != len(header):
                    raise _not_a_table(path, reader.line_num, f"{len(cells)} cells where the header has {len(header)}")
                yield dict(zip(header, cells, strict=True))
    except UnicodeDecodeError as exc:
        raise _not_a_table(path, _line(reader) + 1, f"not UTF-8 text ({exc.reason})") from None
    except csv.Error as exc:
        raise _not_a_table(path, _line(reader), str(exc)) from None


def _line(reader: Any) -> int:
    """The line a CSV reader has reached (counted from 1), 1 before it starts."""
    return max(getattr(reader, "line_num", 1), 1)


def _not_a_table(path: Path, line: int, reason: str) -> PinstabError:
    """The error for a file that is not a sweep table, at ``line`` (counted from 1) of it."""
    return PinstabError(f"{path} is not a sweep table: line {line}: {reason}; give another --out or remove it")


def _drop_cut_line(path: Path) -> None:
    """Cut from the file a last line without its newline (a row cut short by a kill)."""
    with open(path, "rb") as handle:
        end = cut = handle.seek(0, os.SEEK_END)
        while cut > 0:
            start = max(0, cut - CHUNK)
            handle.seek(start)
            block = handle.read(cut - start)
            if cut == end and block.endswith(b"\n"):
                return
            newline = block.rfind(b"\n")
            cut = start if newline < 0 else start + newline + 1
            if newline >= 0:
                break
    if cut < end:
        os.truncate(path, cut)


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
