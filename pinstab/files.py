"""Output files: checked before the work that fills them (:func:`check_output`), then written atomically
(:func:`atomic_output`: a temporary file in the target folder, renamed into place).

A temporary file is named ``.<target name>.pinstab-<pid>-<random><suffix>``; it goes on every exit path of
the writing process, and one left by a process that was killed (``kill -9``, a power cut) is removed by
the next write to the same target. A writer that renames its temporary file itself, when it chooses (a stream,
renamed onto its target before its first row: :mod:`pinstab.stream`), takes it from :func:`temporary_output` and
renames it with :func:`publish`.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .errors import PinstabError

TEMP_MARK = ".pinstab-"
TEMP_EXTRA = 16  # characters mkstemp adds to the prefix: a pid of up to 7 digits, a dash and 8 random ones
DEFAULT_NAME_MAX = DEFAULT_PATH_MAX = 255


def check_output(path: str | Path, suffix: str, kind: str) -> Path:
    """Refuse an output target before any work: the suffix, a folder in its place, a missing or unwritable
    folder, a name or path too long for the file system (the temporary file's name included).

    Args:
        path: the target file. suffix: its required suffix (``.npz``, ``.png``). kind: what the file is.

    Returns:
        The target as a Path.

    Raises:
        PinstabError: naming the path and what is wrong with it.
    """
    target = _checked_target(path, suffix, kind)
    handle, probe = _temporary(target, suffix)
    os.close(handle)
    os.remove(probe)
    return target


@contextmanager
def atomic_output(path: str | Path, suffix: str, kind: str) -> Iterator[str]:
    """Yield a temporary path to write; on success it replaces ``path`` (no half-written files).

    Args:
        path: the target file.
        suffix: required suffix (``.npz``, ``.png``).
        kind: what the file is, for error messages.

    Raises:
        PinstabError: the target is refused (:func:`check_output`).
    """
    target, temp = temporary_output(path, suffix, kind)
    try:  # the temporary file goes on every exit path: an error, Ctrl-C, SIGTERM, or the rename
        yield temp
        publish(temp, target)
    finally:
        if os.path.exists(temp):
            os.remove(temp)


def temporary_output(path: str | Path, suffix: str, kind: str) -> tuple[Path, str]:
    """(the checked target, a new empty temporary file beside it) for a writer that renames the temporary file
    onto the target itself (:func:`publish`); the temporaries of earlier writers killed are removed first.

    Args:
        path: the target file. suffix: its required suffix. kind: what the file is, for error messages.

    Raises:
        PinstabError: the target is refused (:func:`check_output`).
    """
    target = _checked_target(path, suffix, kind)
    remove_stale_temporaries(target)
    handle, temp = _temporary(target, suffix)
    os.close(handle)
    return target, temp


def publish(temp: str | Path, target: Path) -> None:
    """Give the temporary file ``temp`` the permissions of a new file (0666 less the umask: mkstemp makes it 0600)
    and rename it onto ``target``: a file there is replaced, a symbolic link there is replaced, never followed."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(temp, 0o666 & ~umask)
    os.replace(temp, target)


def _checked_target(path: str | Path, suffix: str, kind: str) -> Path:
    """The checks of :func:`check_output` that need no file created: everything but the folder's permission."""
    target = Path(path)
    folder = target.parent
    try:
        folder_is_dir, folder_exists = folder.is_dir(), folder.exists()
    except OSError as exc:  # a folder name over the file system's limit
        raise PinstabError(f"cannot write {path}: {exc.strerror}") from None
    if not folder_is_dir:
        raise PinstabError(
            f"cannot write {path}: folder {folder} {'is not a folder' if folder_exists else 'does not exist'}"
        )
    name_max = _path_limit(folder, "PC_NAME_MAX", DEFAULT_NAME_MAX)
    if len(os.fsencode(target.name)) <= name_max and target.is_dir():  # is_dir fails on a name over the limit
        raise PinstabError(f"{path} is a folder; give a file name ending in {suffix}")
    if target.suffix.lower() != suffix:
        raise PinstabError(f"{path}: the output must be a {suffix} file ({kind})")
    name_bytes = len(os.fsencode(_temp_prefix(target))) + TEMP_EXTRA + len(suffix)
    if name_bytes > name_max:
        own = len(os.fsencode(target.name))
        raise PinstabError(
            f"cannot write {path}: its name is too long ({own} bytes, and its temporary file's {name_bytes}, "
            f"where the folder's file system allows {name_max}); give a name of at most {own - name_bytes + name_max} "
            "bytes"
        )
    path_max = _path_limit(folder, "PC_PATH_MAX", DEFAULT_PATH_MAX)
    if len(os.fsencode(str(target.absolute()))) + name_bytes - len(os.fsencode(target.name)) >= path_max:
        raise PinstabError(f"cannot write {path}: the path is longer than the {path_max} bytes the system allows")
    return target


def _temporary(target: Path, suffix: str) -> tuple[int, str]:
    """mkstemp's (handle, path) of a new temporary file for ``target``; a folder that refuses it is a
    PinstabError."""
    try:
        return tempfile.mkstemp(prefix=_temp_prefix(target), suffix=suffix, dir=target.parent)
    except OSError as exc:
        raise PinstabError(f"cannot write {target}: folder {target.parent} is not writable ({exc.strerror})") from None


def remove_stale_temporaries(target: Path) -> list[Path]:
    """Remove the temporary files of ``target`` left by writers that no longer run; returns them."""
    removed = []
    mark = f".{target.name}{TEMP_MARK}"
    for entry in os.scandir(target.parent):
        pid = entry.name[len(mark) :].partition("-")[0] if entry.name.startswith(mark) else ""
        if pid.isdigit() and not _running(int(pid)):
            Path(entry.path).unlink(missing_ok=True)
            removed.append(Path(entry.path))
    return removed


def _temp_prefix(target: Path) -> str:
    """The name of this process's temporary files for ``target``, before mkstemp's random part."""
    return f".{target.name}{TEMP_MARK}{os.getpid()}-"


def _running(pid: int) -> bool:
    """Whether a process ``pid`` exists."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def _path_limit(folder: Path, name: str, default: int) -> int:
    """The file system's limit ``name`` (os.pathconf) for ``folder``, or ``default`` when unknown."""
    try:
        return os.pathconf(folder, name)
    except (OSError, ValueError):
        return default
