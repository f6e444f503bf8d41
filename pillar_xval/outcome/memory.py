"""How much memory a solve may take in this process.

Models estimate the peak memory of a solve from the scene before building anything
(``bem_solver.estimate_memory``, ``fem_reference.axisym.estimate_memory``,
``fem_reference.solid3d.estimate_memory``) and refuse a scene that
would not fit with a :class:`~pillar_xval.scenes.ScopeError` naming the estimate, instead of
dying of a memory error minutes later.  What binds is the smallest of three limits: the machine's
available memory, the container's (cgroup v2 ``memory.max``) and the process's own
address-space limit (``ulimit -v``), each less what is already used against it.
"""

from __future__ import annotations

import os

__all__ = ["MEMORY_SHARE", "available_memory", "memory_limit", "memory_short"]

# A solve may take this share of the memory available now; beyond it a model refuses it.
MEMORY_SHARE = 0.8
GIB = 2.0**30


def _meminfo(key: str) -> float | None:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


def _machine() -> float:
    """``MemAvailable`` (free memory plus reclaimable caches), else the physical memory."""
    free = _meminfo("MemAvailable")
    if free is not None:
        return free
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return float("inf")


def _read_number(path: str) -> float | None:
    try:
        with open(path) as fh:
            text = fh.read().strip()
        return None if text == "max" else float(text)
    except (OSError, ValueError):
        return None


def _container() -> float | None:
    """Bytes left under the cgroup v2 limit, None where there is none."""
    limit = _read_number("/sys/fs/cgroup/memory.max")
    if limit is None:
        return None
    return max(0.0, limit - (_read_number("/sys/fs/cgroup/memory.current") or 0.0))


def _address_space() -> float | None:
    """Bytes of address space left under ``ulimit -v`` (RLIMIT_AS), None where unlimited."""
    try:
        import resource
    except ImportError:  # not on POSIX
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    used = 0.0
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    used = float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return max(0.0, float(soft) - used)


def memory_limit() -> tuple[float, str]:
    """The bytes a new allocation can take now, and which limit that is."""
    limits = [(_machine(), "available on this machine")]
    container = _container()
    if container is not None:
        limits.append((container, "left under this container's memory limit"))
    address = _address_space()
    if address is not None:
        limits.append((address, "of address space left under this process's limit "
                                "(ulimit -v)"))
    return min(limits, key=lambda item: item[0])


def available_memory() -> float:
    """Bytes a new allocation can take now (the binding limit of :func:`memory_limit`)."""
    return memory_limit()[0]


def memory_short(need_bytes: float) -> str | None:
    """Why a solve of ``need_bytes`` must be refused ("more than 80 % of the 1.9 GiB left
    under ..."), None when it fits in :data:`MEMORY_SHARE` of the binding limit."""
    free, what = memory_limit()
    if need_bytes <= MEMORY_SHARE * free:
        return None
    return f"more than {MEMORY_SHARE:.0%} of the {free / GIB:.3g} GiB {what}"
