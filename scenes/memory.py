"""How much memory a solve may take on this machine.

Models estimate the peak memory of a solve from the scene before building anything
(``bem_solver.estimate_memory``, ``fem_reference.estimate_memory``) and refuse a scene that
would not fit with a :class:`~scenes.ScopeError` naming the estimate, instead of dying of a
memory error minutes later.
"""

from __future__ import annotations

import os

__all__ = ["available_memory"]


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
