"""The limits on the memory a process may still take, as the kernel enforces them: the system's
``MemAvailable``, the memory cgroup of the process (v2 ``memory.max`` less ``memory.current``, v1
``memory.limit_in_bytes`` less ``memory.usage_in_bytes``, at its own level and every ancestor's) and the
address-space limit ``RLIMIT_AS`` (``ulimit -v``, ``prlimit --as``) less the current virtual size
(``VmSize``). The smallest headroom is the one that binds.

A cgroup's usage counts the page cache it may reclaim: its ``inactive_file`` is counted as free. The files
are read under a root directory (``/`` by default) so that a test can give a fake tree.
"""

from __future__ import annotations

import os
import resource
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path("/")
FRESH_FOR = 0.5  # [s]: how long a reading of the real limits is reused
_recent: list = []  # [monotonic time, MemorySource] of the last reading under ROOT
UNLIMITED = 2**60  # [bytes]: a cgroup v1 limit at or above it is "no limit" (the kernel writes 2^63 - a page)
V2_MOUNTS = ("sys/fs/cgroup", "sys/fs/cgroup/unified")  # unified, or hybrid (v1 controllers beside)
V1_MOUNT = "sys/fs/cgroup/memory"
V1_LIMIT = "memory.limit_in_bytes"
# version -> (mount points, the file that marks the mount, limit file, usage file, reclaimable key of memory.stat)
HIERARCHIES = {
    "v2": (V2_MOUNTS, "cgroup.controllers", "memory.max", "memory.current", "inactive_file"),
    "v1": ((V1_MOUNT,), V1_LIMIT, V1_LIMIT, "memory.usage_in_bytes", "total_inactive_file"),
}


@dataclass(frozen=True)
class MemorySource:
    """One limit on the memory the process may still take.

    Attributes:
        name: the limit, as a user would look it up (``MemAvailable``, ``cgroup v2 memory.max of /a/b``,
            ``RLIMIT_AS``). limit: its value [bytes]. free: what it leaves the process now [bytes].
    """

    name: str
    limit: int
    free: int

    def describe(self) -> str:
        """'1.55 GB left by the address-space limit RLIMIT_AS (ulimit -v, prlimit --as) of 2 GB', for messages."""
        if self.name == "MemAvailable":
            return f"{format_size(self.free)} the system has available (MemAvailable)"
        return f"{format_size(max(self.free, 0))} left by {self.name} of {format_size(self.limit)}"


def format_size(size: float) -> str:
    """A size in bytes for people: ``2.7 GB``, ``350 MB``, ``12 kB``."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return f"{int(size)} B"


def memory_sources(root: Path = ROOT) -> list[MemorySource]:
    """Every limit that applies to this process (``MemAvailable`` always; cgroup and RLIMIT_AS when set)."""
    sources = [_available(root)]
    cgroups = _cgroup_paths(root)
    for version, path in cgroups.items():
        sources += _cgroup_limits(root, path, version)
    sources += _address_space(root)
    return sources


def tightest(root: Path = ROOT) -> MemorySource:
    """The limit that leaves the least memory free. Under the real root a reading is reused for
    :data:`FRESH_FOR` seconds: a run checks its budget several times in its first milliseconds, and each reading
    costs ~0.2-0.3 ms (the cgroup tree's files)."""
    if root != ROOT:
        return min(memory_sources(root), key=lambda source: source.free)
    now = time.monotonic()
    if not _recent or now - _recent[0] > FRESH_FOR:
        _recent[:] = [now, min(memory_sources(root), key=lambda source: source.free)]
    return _recent[1]


def _available(root: Path) -> MemorySource:
    """``MemAvailable`` of ``/proc/meminfo``, else the physical memory."""
    free = _meminfo(root / "proc/meminfo", "MemAvailable:")
    if free is None:
        free = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    return MemorySource("MemAvailable", free, free)


def _meminfo(path: Path, key: str) -> int | None:
    """The ``key`` line of a ``/proc`` status file in kB, as bytes; None when absent or unreadable."""
    try:
        for line in path.read_text().splitlines():
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_paths(root: Path) -> dict[str, str]:
    """The process's cgroup path per hierarchy (``v2``: the ``0::`` line; ``v1``: the memory controller's)."""
    try:
        lines = (root / "proc/self/cgroup").read_text().splitlines()
    except OSError:
        return {}
    paths = {}
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        if parts[0] == "0" and parts[1] == "":
            paths["v2"] = parts[2]
        elif "memory" in parts[1].split(","):
            paths["v1"] = parts[2]
    return paths


def _cgroup_limits(root: Path, path: str, version: str) -> list[MemorySource]:
    """The limited levels of the process's cgroup, from its own up to the mount's root (a limit binds
    every descendant). In a cgroup namespace, or a container mounting only its own cgroup, the path may not
    exist under the mount: the nearest existing ancestor stands for it."""
    mounts, marker = HIERARCHIES[version][:2]
    mount = next((root / m for m in mounts if (root / m / marker).is_file()), None)
    if mount is None:
        return []
    level = mount / path.lstrip("/")
    while level != mount and not level.is_dir():
        level = level.parent
    sources = []
    while True:
        source = _cgroup_level(level, mount, version)
        if source is not None:
            sources.append(source)
        if level == mount:
            return sources
        level = level.parent


def _cgroup_level(level: Path, mount: Path, version: str) -> MemorySource | None:
    """The limit of one cgroup directory, or None when it has none (``max``, v1's unlimited) or none is readable."""
    limit_file, usage_file, cache_key = HIERARCHIES[version][2:]
    try:
        limit_text = (level / limit_file).read_text().strip()
        usage = int((level / usage_file).read_text().strip())
    except (OSError, ValueError):
        return None
    if limit_text == "max" or not limit_text.isdigit() or int(limit_text) >= UNLIMITED:
        return None
    reclaimable = 0
    try:
        for line in (level / "memory.stat").read_text().splitlines():
            key, _, value = line.partition(" ")
            if key == cache_key:
                reclaimable = int(value)
    except (OSError, ValueError):
        pass
    limit = int(limit_text)
    relative = level.relative_to(mount).as_posix()
    name = f"the cgroup {version} limit {limit_file} of /{'' if relative == '.' else relative}"
    return MemorySource(name, limit, limit - max(usage - reclaimable, 0))


def _address_space(root: Path) -> list[MemorySource]:
    """``RLIMIT_AS`` (soft) less the current virtual size ``VmSize``, when the limit is set."""
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return []
    size = _meminfo(root / "proc/self/status", "VmSize:") or 0
    return [MemorySource("the address-space limit RLIMIT_AS (ulimit -v, prlimit --as)", soft, soft - size)]
