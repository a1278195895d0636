"""How much memory a process can still get, and the size check that refuses work beyond it.

Free RAM is not the only bound: an address-space limit (``ulimit -v``, ``RLIMIT_AS``) or a container's
memory cap (a cgroup's ``memory.max``) stops an allocation long before the machine runs out, with a raw
``MemoryError``. :func:`memory_headroom` takes the smallest of all of them, so :func:`check_memory` can
refuse in one line before the arrays are allocated.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import ConfigError

__all__ = [
    "physical_memory",
    "available_memory",
    "address_space_headroom",
    "cgroup_headroom",
    "memory_headroom",
    "check_memory",
]

#: A cgroup "limit" at or above this is no limit (cgroup v1 writes 2**63 rounded down to a page).
_NO_LIMIT = 2**60


def physical_memory() -> int | None:
    """This machine's physical memory in bytes (None where the OS does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def _read_number(path: Path | str, key: str | None = None) -> int | None:
    """The integer in file ``path`` (or on its line starting with ``key``, in kB); None if absent or not a number."""
    try:
        with open(path, encoding="ascii") as f:
            if key is None:
                return int(f.read().strip())
            for line in f:
                if line.startswith(key):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def available_memory() -> int | None:
    """Memory the OS can give a process now, in bytes (Linux ``MemAvailable``; None where unknown)."""
    return _read_number("/proc/meminfo", "MemAvailable:")


def address_space_headroom() -> int | None:
    """Bytes of address space this process may still map under its ``RLIMIT_AS`` (None: no such limit)."""
    try:
        import resource
    except ImportError:  # not a POSIX system
        return None
    soft, _hard = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    used = _read_number("/proc/self/status", "VmSize:") or 0
    return max(0, soft - used)


def _cgroup_dirs(root: Path, own: Path) -> list[tuple[Path, str, str]]:
    """(folder, limit file, usage file) of this process's memory cgroup and its ancestors, v2 and v1
    (``own``: the process's ``/proc/self/cgroup``, ``root``: where the cgroup file systems are mounted)."""
    out: list[tuple[Path, str, str]] = []
    try:
        lines = own.read_text(encoding="ascii", errors="replace").splitlines()
    except OSError:
        return out
    for line in lines:
        _id, _sep, rest = line.partition(":")
        controllers, _sep, where = rest.partition(":")
        if controllers == "":  # v2: one unified hierarchy
            base, files = root, ("memory.max", "memory.current")
        elif "memory" in controllers.split(","):  # v1: the memory controller's own hierarchy
            base, files = root / "memory", ("memory.limit_in_bytes", "memory.usage_in_bytes")
        else:
            continue
        parts = [p for p in where.split("/") if p]
        for k in range(len(parts), -1, -1):  # the cgroup itself, then every ancestor (their caps apply too)
            out.append((base.joinpath(*parts[:k]), *files))
    return out


def cgroup_headroom(root: Path = Path("/sys/fs/cgroup"), own: Path = Path("/proc/self/cgroup")) -> int | None:
    """Bytes this process's cgroup (a container's memory cap) still allows (None: no cap found); the
    smallest over the cgroup and its ancestors, whose caps apply as well."""
    room = None
    for folder, limit_file, usage_file in _cgroup_dirs(root, own):
        limit = _read_number(folder / limit_file)  # v2 writes "max" for no limit: not a number, skipped
        if limit is None or limit >= _NO_LIMIT:
            continue
        left = max(0, limit - (_read_number(folder / usage_file) or 0))
        room = left if room is None else min(room, left)
    return room


def memory_headroom() -> tuple[int | None, str]:
    """The fewest bytes any bound lets this process allocate now, and which bound that is (in words)."""
    bounds = [
        (physical_memory(), "this machine's memory"),
        (available_memory(), "this machine's free memory"),
        (address_space_headroom(), "this process's address-space limit (ulimit -v)"),
        (cgroup_headroom(), "the memory limit of this process's cgroup (container)"),
    ]
    known = [(b, why) for b, why in bounds if b is not None]
    if not known:
        return None, "unknown"
    return min(known, key=lambda x: x[0])


def check_memory(what: str, nbytes: float, advice: str, error: type = ConfigError) -> None:
    """Refuse work whose arrays alone would take more than 3/4 of what this process can get now: the least of
    free (else physical) memory, the address-space limit and a cgroup's memory limit.

    The message says how large they would be and which bound refuses them, so a front end can show it as
    one line.
    """
    limit, why = memory_headroom()
    if limit is not None and nbytes > 0.75 * limit:
        raise error(
            f"{what} would need {nbytes / 2**30:.1f} GiB of memory for its arrays, more than this process can "
            f"get now ({limit / 2**30:.1f} GiB: {why}); {advice}"
        )
