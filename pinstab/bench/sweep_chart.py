"""A chart of a sweep's table: one column against another, coloured by a third (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import PinstabError
from .sweep_table import table_rows


def check_chart(names: list[str | None], columns: list[str]) -> None:
    """Refuse a chart column that the table does not have, listing the columns it has."""
    for name in names:
        if name is not None and name not in columns:
            raise PinstabError(f"--chart: no column {name!r} in the sweep's table; columns: {', '.join(columns)}")


def draw_chart(table: str | Path, x: str, y: str, png: str | Path, color: str | None = None, title: str = "") -> int:
    """Draw column ``y`` against column ``x`` of the sweep's ``table`` into ``png``, one marker per point that
    ran (rows with an error left out, counted in the title); ``color``: a column whose values colour the
    markers (a legend for names and booleans, a colour bar for numbers). Returns the number of points drawn.

    Raises:
        PinstabError: a column the table does not have (:func:`check_chart`), no point without an error.
    """
    from ..plotting import pyplot, save_figure

    rows = table_rows(table)
    check_chart([x, y, color], list(rows[0]) if rows else [x, y, color])
    ran = [row for row in rows if not row.get("error") and row[x] is not None and row[y] is not None]
    if not ran:
        raise PinstabError(f"--chart: no point of {table} ran without an error: nothing to draw")
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=110)
    groups = _groups(ran, color)
    if groups is None:
        drawn = ax.scatter([r[x] for r in ran], [r[y] for r in ran], c=[r[color] for r in ran], cmap="viridis", s=40)
        fig.colorbar(drawn, ax=ax, label=color)
    else:
        for value, members in groups.items():
            label = None if color is None else f"{color} = {value}"
            ax.scatter([r[x] for r in members], [r[y] for r in members], s=40, label=label)
        if color is not None:
            ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    failed = len(rows) - len(ran)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(f"{title}{f' ({failed} failed points not drawn)' if failed else ''}", fontsize=9)
    ax.grid(True, alpha=0.3)
    save_figure(fig, png)
    return len(ran)


def _groups(rows: list[dict[str, Any]], color: str | None) -> dict[Any, list[dict[str, Any]]] | None:
    """The rows by their ``color`` value when it is a name or a boolean (one group without ``color``); None
    when the values are numbers (a colour scale)."""
    values = [row[color] for row in rows] if color is not None else [None] * len(rows)
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in values) and color is not None:
        return None
    groups: dict[Any, list[dict[str, Any]]] = {}
    for value, row in zip(values, rows, strict=True):
        groups.setdefault(value, []).append(row)
    return groups
