"""A sweep's table, written a row at a time so that a killed sweep resumes: CSV (standard library) or Parquet
(pyarrow, the ``sweep`` extra).

The rows go to a CSV journal, each flushed when written: the ``.csv`` itself, or ``FILE.parquet.partial.csv``
beside a Parquet target, converted to ``FILE.parquet`` (atomically) when the sweep ends and then removed. On
opening, the points already in the journal (or in an existing Parquet file) are :attr:`SweepTable.done`; a last
line cut short by a kill is dropped.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..errors import PinstabError
from ..files import atomic_output, check_output

SUFFIXES = (".csv", ".parquet")
JOURNAL = ".partial.csv"  # appended to a Parquet target's name


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
            table = _pyarrow().parquet.read_table(self.path)
            _check_columns(self.path, table.column_names, columns)
            self._write_journal(table.to_pylist())
        rows = read_rows(self.journal, columns) if self.journal.exists() else []
        keyed = [(point_key(row[name] for name in columns[:keys]), row["error"]) for row in rows]
        self.done = {key for key, _ in keyed}
        self.failed = {key for key, error in keyed if error}
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


def read_rows(path: str | Path, columns: list[str] | None = None) -> list[dict[str, str]]:
    """The rows of a sweep's CSV (the journal of a Parquet table too) as text; a last line cut short by a kill
    is dropped (and cut from the file).

    Args:
        path: the CSV. columns: the columns it must have (None: any).

    Raises:
        PinstabError: other columns than ``columns`` (a table of another sweep).
    """
    path = Path(path)
    text = path.read_text()
    if text and not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
        with open(path, "r+") as handle:
            handle.truncate(len(text.encode()))
    reader = csv.DictReader(text.splitlines())
    if columns is not None and reader.fieldnames is not None:
        _check_columns(path, reader.fieldnames, columns)
    return list(reader)


def _check_columns(path: Path, found: list[str], columns: list[str]) -> None:
    """Refuse a table whose columns are not this sweep's.

    Raises:
        PinstabError: naming the file and the columns it holds.
    """
    if list(found) != columns:
        raise PinstabError(
            f"{path} holds another sweep's table (columns {', '.join(found)}); give another --out or remove it"
        )


def table_rows(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a sweep's table, CSV or Parquet, with numbers, booleans and None (an empty cell) as such."""
    path = Path(path)
    if path.suffix == ".parquet":
        return _pyarrow().parquet.read_table(path).to_pylist()
    return [{name: _cell(text) for name, text in row.items()} for row in read_rows(path)]


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
