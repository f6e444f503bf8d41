"""How much memory a solve may take on this machine.

Models estimate the peak memory of a solve from the scene before building anything
(``bem_solver.estimate_memory``, ``fem_reference.axisym.estimate_memory``,
``fem_reference.solid3d.estimate_memory``) and refuse a scene that
would not fit with a :class:`~scenes.ScopeError` naming the estimate, instead of dying of a
memory error minutes later.
"""

from __future__ import annotations

import os

__all__ = ["MEMORY_SHARE", "available_memory", "memory_short"]

# A solve may take this share of the memory available now; beyond it a model refuses it.
MEMORY_SHARE = 0.8


def available_memory() -> float:
    """Bytes a new allocation can take now: ``MemAvailable`` of /proc/meminfo (free memory
    plus reclaimable caches), or the physical memory where that is not readable."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return float("inf")


def memory_short(need_bytes: float) -> float | None:
    """The bytes available when ``need_bytes`` exceeds :data:`MEMORY_SHARE` of them (the
    solve must be refused), None when it fits."""
    free = available_memory()
    return free if need_bytes > MEMORY_SHARE * free else None
