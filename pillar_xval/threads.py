"""How many threads a solve may use in this process, and the libraries held to that count.

The count is the CPUs the process may run on: its affinity mask (``taskset``, a batch
system's CPU set) further limited by the CPU quota of its control group (cgroup v2
``cpu.max``, v1 ``cpu.cfs_quota_us`` / ``cpu.cfs_period_us``; a container's ``--cpus``),
whole CPUs, at least one.  One override sets it: the environment variable
:data:`THREADS_ENV` (the CLI's ``--threads`` sets it for the command and its workers; the
study engine sets each worker's share).  Every threaded part of the toolkit reads
:func:`thread_count`: scipy.fft's workers, the pillar boxes' transforms, the dense BEM's
assembly threads, gmsh's meshing, and, through :func:`limited` (threadpoolctl), BLAS, MKL
(PARDISO included) and the OpenMP runtimes.  A few memory-bound parts use fewer by
measurement, never more: fem-3d's back-substitutions of few columns and its element blocks'
products, and the half-space model's dense algebra, run on one thread.
"""

from __future__ import annotations

import math
import os
import sys
from contextlib import contextmanager
from pathlib import Path

from pillar_xval.scenes import InputError

__all__ = ["MAX_THREADS", "THREADS_ENV", "cgroup_cpus", "cpu_count", "limited", "limiter",
           "thread_count", "threads_override"]

THREADS_ENV = "PILLAR_XVAL_THREADS"
# A bound on the override against typing slips (a thread costs its stack and buffers); no
# machine's core count.
MAX_THREADS = 1024


def _affinity() -> int:
    """CPUs in this process's affinity mask (all the machine's where there is none)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        return os.cpu_count() or 1


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except (OSError, UnicodeDecodeError):
        return None


def _ancestors(base: Path, relative: str) -> list[Path]:
    """``base / relative`` and each of its parents up to ``base`` (a quota set on a parent
    group binds its children too)."""
    parts = [p for p in relative.split("/") if p]
    return [base.joinpath(*parts[:k]) for k in range(len(parts), -1, -1)]


def _v2_quota(folder: Path) -> float | None:
    """CPUs of a cgroup v2 ``cpu.max`` ("max PERIOD" or "QUOTA PERIOD"), None if none."""
    text = _read(folder / "cpu.max")
    if not text:
        return None
    fields = text.split()
    try:
        if fields[0] == "max":
            return None
        quota, period = float(fields[0]), float(fields[1]) if len(fields) > 1 else 1e5
    except (ValueError, IndexError):
        return None
    return quota / period if quota > 0 and period > 0 else None


def _v1_quota(folder: Path) -> float | None:
    """CPUs of a cgroup v1 ``cpu.cfs_quota_us`` over ``cpu.cfs_period_us`` (-1: none)."""
    try:
        quota = float(_read(folder / "cpu.cfs_quota_us") or "-1")
        period = float(_read(folder / "cpu.cfs_period_us") or "0")
    except ValueError:
        return None
    return quota / period if quota > 0 and period > 0 else None


def cgroup_cpus(root: str | Path = "/sys/fs/cgroup",
                membership: str | Path = "/proc/self/cgroup") -> float | None:
    """CPUs the control groups' quotas allow this process (quota over period, possibly
    fractional; the smallest along its groups and their parents, v2 and v1 alike), None
    when no quota applies or none can be read."""
    root = Path(root)
    lines = (_read(Path(membership)) or "").splitlines()
    found = []
    for line in lines:
        fields = line.split(":", 2)
        if len(fields) != 3:
            continue
        _, controllers, relative = fields
        if controllers == "":  # the v2 unified hierarchy ("0::/path")
            folders, read = _ancestors(root, relative), _v2_quota
        elif "cpu" in controllers.split(","):  # v1: mounted as cpu or cpu,cpuacct
            folders = [f for name in ("cpu", "cpu,cpuacct", "cpuacct,cpu")
                       for f in _ancestors(root / name, relative)]
            read = _v1_quota
        else:
            continue
        found += [q for q in map(read, folders) if q is not None]
    if not lines:  # no membership file: the v2 root alone
        found += [q for q in [_v2_quota(root)] if q is not None]
    return min(found) if found else None


def cpu_count() -> int:
    """Whole CPUs this process may use: its affinity mask, limited by its cgroup quota
    (rounded down: a share of a CPU is not a thread's worth), at least 1."""
    cpus = _affinity()
    quota = cgroup_cpus()
    if quota is not None:
        cpus = min(cpus, max(1, math.floor(quota + 1e-9)))
    return max(1, cpus)


def thread_count() -> int:
    """Threads a solve may use: :data:`THREADS_ENV` when set (an integer in
    [1, :data:`MAX_THREADS`]; anything else is an InputError naming it), else
    :func:`cpu_count`."""
    text = os.environ.get(THREADS_ENV, "").strip()
    if not text:
        return cpu_count()
    if not text.isdigit() or not 1 <= int(text) <= MAX_THREADS:
        raise InputError(f"{THREADS_ENV} = {text!r}: expected a whole number of threads in "
                         f"[1, {MAX_THREADS}] (this process may use {cpu_count()} CPUs)")
    return int(text)


@contextmanager
def threads_override(count: int | None):
    """Set :data:`THREADS_ENV` to ``count`` inside the block (None: leave it as it is), for
    this process and the processes it starts; restored on the way out."""
    if count is None:
        yield
        return
    before = os.environ.get(THREADS_ENV)
    os.environ[THREADS_ENV] = str(int(count))
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(THREADS_ENV, None)
        else:
            os.environ[THREADS_ENV] = before


_CONTROLLERS: dict = {}


def _controller():
    """threadpoolctl's controller of the libraries loaded now.  Finding them takes 2-4 ms
    (as long as a closed-form solve), so it is found again only when Python has imported
    modules since (a BLAS or OpenMP runtime comes with a module that loads it; MKL, which
    pypardiso loads later, is held by PARDISO's own :func:`limiter`)."""
    from threadpoolctl import ThreadpoolController

    key = (os.getpid(), len(sys.modules))
    found = _CONTROLLERS.get(key)
    if found is None:
        _CONTROLLERS.clear()
        found = _CONTROLLERS[key] = ThreadpoolController()
    return found


def limiter(count: int | None = None):
    """A function that returns a context holding the BLAS, MKL and OpenMP libraries loaded
    now to ``count`` threads (default :func:`thread_count`), some 0.1 ms a use: a caller
    that enters it often (PARDISO's solves) keeps the function; a library loaded later is not
    held by it."""
    from threadpoolctl import ThreadpoolController

    n = thread_count() if count is None else int(count)
    controller = ThreadpoolController()
    return lambda: controller.limit(limits=n)


def limited(count: int | None = None):
    """A context holding the BLAS, MKL and OpenMP libraries loaded now to ``count`` threads
    (default :func:`thread_count`); their previous counts come back on the way out."""
    return _controller().limit(limits=thread_count() if count is None else int(count))
