"""Output files written atomically: a temporary file in the target folder, renamed into place."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .errors import PinstabError


@contextmanager
def atomic_output(path: str | Path, suffix: str, kind: str) -> Iterator[str]:
    """Yield a temporary path to write; on success it replaces ``path`` (no half-written files).

    Args:
        path: the target file.
        suffix: required suffix (``.npz``, ``.png``).
        kind: what the file is, for error messages.
    """
    target = Path(path)
    if target.suffix.lower() != suffix:
        raise PinstabError(f"{kind} files are {suffix}; got {target.name!r}")
    if not target.parent.is_dir():
        raise PinstabError(f"cannot write {target}: folder {target.parent} does not exist")
    handle, temp = tempfile.mkstemp(suffix=suffix, dir=target.parent)
    try:  # the temporary file goes on every exit path: an error, Ctrl-C, or the rename
        os.close(handle)
        yield temp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temp, 0o666 & ~umask)
        os.replace(temp, target)
    finally:
        if os.path.exists(temp):
            os.remove(temp)
