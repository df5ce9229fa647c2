"""matplotlib, headless, as an optional extra (``pip install pinstab[plot]``); atomic PNG writes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .errors import PinstabError
from .files import atomic_output


def pyplot() -> Any:
    """matplotlib.pyplot with the non-interactive Agg backend, or a PinstabError with the install hint."""
    try:
        import matplotlib
    except ImportError:
        raise PinstabError("charts need matplotlib: pip install 'pinstab[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Any, path: str | Path) -> Path:
    """Save a figure as PNG atomically, then close it."""
    try:
        with atomic_output(path, ".png", "chart") as temp:
            fig.savefig(temp, format="png", bbox_inches="tight")
    finally:
        pyplot().close(fig)
    return Path(path)
