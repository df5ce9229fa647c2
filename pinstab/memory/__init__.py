"""The memory budget: what a command will allocate, estimated before it allocates, and refused when the
estimate exceeds the limit.

The limit is :data:`DEFAULT_FRACTION` of the memory the tightest of the process's limits leaves at each
check (:mod:`pinstab.memory.limits`: ``MemAvailable``, the memory cgroup v1/v2, ``RLIMIT_AS``), or the one
set with :func:`memory_limit` (the command line's ``--memory-limit``). The big items are the samples a run keeps
and Pinocchio's ``Data``: pinstab builds its own without the second-order derivative tensors (:func:`new_data`, about
300 nv^2 bytes, 7 MB for nv = 161), but Pinocchio's constructor, which its parsers call, allocates them (about
52 nv^3 bytes, 1.4 GB for nv = 301). A ``MemoryError`` that happens anyway (an estimate exceeded, another process
taking the memory) becomes a :class:`~pinstab.errors.MemoryBudgetError` naming what needed the memory and the
tightest limit (:func:`named_when_exhausted`).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import pinocchio as pin

from .._compiled import light_data
from ..errors import MemoryBudgetError, PinstabError
from .limits import MemorySource, format_size, tightest

DEFAULT_FRACTION = 0.8  # of the memory available when checked (before the allocations, at the start)
# doubles per nv^2 and per joint of a Data without the derivative tensors (new_data, the compiled kernels' own)
DATA_SQUARE, DATA_FIXED = 40, 1500
DATA_CUBIC = 6.5  # doubles per nv^3 more in a Data of Pinocchio's constructor (its four nv^3 derivative tensors)
# Data a run holds at most: the model's scratch, its kinematics' (built at first use: never on the banded path, whose
# kernel computes in the scratch) and a compiled kernel's own (the native, servo or grasp kernel's)
RUN_DATA_COPIES = 3
SAMPLE_SERIES = 16  # doubles a kept sample adds besides q, v, multipliers: time, drifts, energy, copies written
UNITS = {"": 1, "b": 1, "kb": 10**3, "mb": 10**6, "gb": 10**9, "tb": 10**12}
UNITS |= {"kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40}

_limit: ContextVar[int | None] = ContextVar("pinstab_memory_limit", default=None)


def available_bytes() -> int:
    """The memory this process may still take [bytes]: the least that its limits leave (``MemAvailable``, its
    memory cgroup, ``RLIMIT_AS``; :func:`~pinstab.memory.limits.tightest`)."""
    return tightest().free


def limit_bytes() -> int:
    """The budget in force [bytes]: the one set by :func:`memory_limit`, else :data:`DEFAULT_FRACTION` of
    :func:`available_bytes`."""
    return budget()[0]


def budget() -> tuple[int, str]:
    """(the budget in force [bytes], where it comes from, for messages)."""
    limit = _limit.get()
    if limit is not None:
        return limit, "set with --memory-limit or pinstab.memory_limit"
    source = tightest()
    return int(DEFAULT_FRACTION * max(source.free, 0)), f"{DEFAULT_FRACTION:.0%} of the {source.describe()}"


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


def data_bytes(nv: int, njoints: int, tensors: bool = False) -> int:
    """An upper estimate of one Pinocchio ``Data`` [bytes] for a model of ``nv`` velocities and ``njoints``
    joints: one of :func:`new_data` (calibrated on Pinocchio 4.1: within a factor 2.5 above the measured resident
    size from nv = 41 to 301), or with ``tensors`` one of Pinocchio's constructor, which adds its four nv^3
    derivative tensors (``pin.Data(model)``, the one its parsers build)."""
    cubic = round(DATA_CUBIC * nv**3) if tensors else 0
    return 8 * (cubic + DATA_SQUARE * nv**2 + DATA_FIXED * njoints)


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
    limit, source = budget()
    if total <= limit:
        return
    parts = ", ".join(f"{name} {format_size(size)}" for name, size in sorted(items.items(), key=lambda i: -i[1]))
    raise MemoryBudgetError(
        f"{what} needs about {format_size(total)} of memory ({parts}), more than the limit of "
        f"{format_size(limit)} ({source}); {remedy}, or raise the limit if the machine has the memory "
        f"(--memory-limit {format_size(2 * total).replace(' ', '')}; pinstab.memory_limit in Python)",
        estimate=total,
        limit=limit,
        source=source,
        needed_by=what,
    )


def exhausted(what: str, error: MemoryError, trajectory=None) -> MemoryBudgetError:
    """The MemoryBudgetError for a ``MemoryError`` raised while doing ``what``: it names the tightest limit
    of the process and keeps ``trajectory`` (the samples of a run up to then, or None)."""
    source: MemorySource = tightest()
    detail = f" ({error})" if str(error) else ""
    kept = "" if trajectory is None else f"; the run's samples up to t = {trajectory.t[-1]:.6g} s are kept"
    return MemoryBudgetError(
        f"{what} ran out of memory{detail}: the tightest limit on this process: {source.describe()}{kept}; "
        "make the scene smaller, keep fewer samples (--record-every), or run where the limit is higher",
        estimate=None,
        limit=max(source.free, 0),
        source=source.name,
        needed_by=what,
        trajectory=trajectory,
    )


@contextmanager
def named_when_exhausted(what: str) -> Iterator[None]:
    """Turn a ``MemoryError`` inside the ``with`` block into :func:`exhausted`'s MemoryBudgetError about ``what``."""
    try:
        yield
    except MemoryError as error:
        raise exhausted(what, error) from None


def new_data(model: pin.Model) -> pin.Data:
    """A ``pin.Data`` of ``model`` without Pinocchio's second-order derivative tensors, after checking that it fits
    the budget.

    Built by ``cpp/light_data.cpp``: every member Pinocchio 4.1's constructor sets, but the kinematic Hessians and
    the four nv^3 second-order RNEA derivatives (``pin.Data(model)`` allocates and zeroes them: 135 MiB and ~50 ms at
    the N-four-bar N = 80, ``python benchmarks/data_creation.py``), which no pass pinstab runs reads (do not hand it
    to ``computeJointKinematicHessians`` or ``computeRNEASecondOrderDerivatives``).

    Raises:
        MemoryBudgetError: naming the model's size, the estimate and the limit.
    """
    what = model_size(model)
    require({"one Pinocchio Data": data_bytes(model.nv, model.njoints)}, what)
    with named_when_exhausted(f"the Pinocchio Data of {what}"):
        return light_data(model)


def model_size(model: pin.Model) -> str:
    """'a model of N velocities and J joints', for messages."""
    return f"a model of {model.nv} velocities and {model.njoints - 1} joints"
