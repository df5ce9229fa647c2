"""matplotlib, headless, as an optional extra (``pip install pinstab[plot]``); atomic PNG writes."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

from .errors import PinstabError


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
    """Save a figure as PNG through a temporary file in the target folder, then close it."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise PinstabError(f"charts are written as .png; got {path.name!r}")
    if not path.parent.is_dir():
        raise PinstabError(f"cannot write {path}: folder {path.parent} does not exist")
    handle, temp = tempfile.mkstemp(suffix=".png", dir=path.parent)
    os.close(handle)
    try:
        fig.savefig(temp, format="png", bbox_inches="tight")
        os.replace(temp, path)
    finally:
        if os.path.exists(temp):
            os.remove(temp)
        pyplot().close(fig)
    return path
