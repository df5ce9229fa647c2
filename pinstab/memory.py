"""The memory budget: what a command will allocate, estimated before it allocates, and refused when the
estimate exceeds the limit.

The limit is :data:`DEFAULT_FRACTION` of the memory available at each check (``MemAvailable`` of
``/proc/meminfo``), or the one set with :func:`memory_limit` (the command line's ``--memory-limit``).
The big items are Pinocchio's ``Data`` (its derivative tensors grow with nv^3: about 52 nv^3 bytes, 1.4 GB
for nv = 301) and the samples a run keeps.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import pinocchio as pin

from .errors import MemoryBudgetError, PinstabError

DEFAULT_FRACTION = 0.8  # of the memory available when checked (before the allocations, at the start)
DATA_CUBIC, DATA_SQUARE, DATA_FIXED = 6.5, 100, 3000  # doubles per nv^3, nv^2 and joint of a Pinocchio Data
RUN_DATA_COPIES = 3  # Pinocchio Data a run holds: the constrained model's two and its solver's
SAMPLE_SERIES = 16  # doubles a kept sample adds besides q, v, multipliers: time, drifts, energy, copies written
UNITS = {"": 1, "b": 1, "kb": 10**3, "mb": 10**6, "gb": 10**9, "tb": 10**12}
UNITS |= {"kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40}

_limit: ContextVar[int | None] = ContextVar("pinstab_memory_limit", default=None)


def available_bytes() -> int:
    """The memory the system can give without swapping [bytes]: ``MemAvailable``, else the physical memory."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def limit_bytes() -> int:
    """The budget in force [bytes]: the one set by :func:`memory_limit`, else :data:`DEFAULT_FRACTION` of
    :func:`available_bytes`."""
    limit = _limit.get()
    return int(DEFAULT_FRACTION * available_bytes()) if limit is None else limit


@contextmanager
def memory_limit(limit: int | str) -> Iterator[int]:
    """Set the budget (bytes, or a size such as ``"4 GB"``, ``"512MiB"``) inside the ``with`` block."""
    token = _limit.set(parse_size(limit) if isinstance(limit, str) else _positive(limit, str(limit)))
    try:
        yield _limit.get()
    finally:
        _limit.reset(token)


def parse_size(text: str) -> int:
    """``"4 GB"`` -> 4e9 bytes: a positive number with an optional unit B, kB, MB, GB, TB, KiB, MiB, GiB, TiB
    (decimal or binary; letter case ignored; no unit means bytes)."""
    match = re.fullmatch(r"\s*([0-9.eE+-]+)\s*([A-Za-z]*)\s*", text)
    unit = match.group(2).lower() if match else ""
    if match is None or unit not in UNITS:
        raise PinstabError(f"memory limit {text!r} is not a size: give a number and one of B, kB, MB, GB, TB, GiB")
    try:
        value = float(match.group(1)) * UNITS[unit]
    except ValueError:
        raise PinstabError(f"memory limit {text!r} is not a size: {match.group(1)!r} is not a number") from None
    return _positive(value, text)


def _positive(value: float, text: str) -> int:
    if not value >= 1 or value == float("inf"):
        raise PinstabError(f"memory limit {text!r} must be a positive, finite size")
    return int(value)


def format_size(size: float) -> str:
    """A size in bytes for people: ``2.7 GB``, ``350 MB``, ``12 kB``."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{int(size)} B"


def data_bytes(nv: int, njoints: int) -> int:
    """An upper estimate of one Pinocchio ``Data`` [bytes] for a model of ``nv`` velocities and ``njoints``
    joints (calibrated on Pinocchio 4.1: within a factor 2 above the measured resident size from nv = 10 to
    300)."""
    return 8 * (round(DATA_CUBIC * nv**3) + DATA_SQUARE * nv**2 + DATA_FIXED * njoints)


def samples_bytes(samples: int, nq: int, nv: int, rows: int) -> int:
    """The kept samples of a run and the series computed from them [bytes]: per sample q, v, the
    multipliers and :data:`SAMPLE_SERIES` more doubles."""
    return 8 * samples * (nq + nv + rows + SAMPLE_SERIES)


def require(items: dict[str, int], what: str, remedy: str = "make the scene smaller") -> None:
    """Refuse ``what`` when the estimated ``items`` (name -> bytes) together exceed the budget; the message
    offers ``remedy`` first.

    Raises:
        MemoryBudgetError: naming the estimate, its largest items and the limit, and how to change it.
    """
    total = sum(items.values())
    limit = limit_bytes()
    if total <= limit:
        return
    parts = ", ".join(f"{name} {format_size(size)}" for name, size in sorted(items.items(), key=lambda i: -i[1]))
    raise MemoryBudgetError(
        f"{what} needs about {format_size(total)} of memory ({parts}), more than the limit of "
        f"{format_size(limit)}; {remedy}, or raise the limit if the machine has the memory (--memory-limit "
        f"{format_size(2 * total).replace(' ', '')}; pinstab.memory_limit in Python)",
        estimate=total,
        limit=limit,
    )


def new_data(model: pin.Model) -> pin.Data:
    """``model.createData()`` after checking that one ``Data`` of this model fits the budget.

    Raises:
        MemoryBudgetError: naming the model's size, the estimate and the limit.
    """
    require({"one Pinocchio Data": data_bytes(model.nv, model.njoints)}, model_size(model))
    return model.createData()


def model_size(model: pin.Model) -> str:
    """'a model of N velocities and J joints', for messages."""
    return f"a model of {model.nv} velocities and {model.njoints - 1} joints"
