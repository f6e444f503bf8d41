"""Where cases run: in this process, in a local pool of processes, or on a Dask cluster.

Every executor offers ``capacity`` (cases worth keeping in flight), ``submit(fn, arg)`` (a
future with ``done``, ``result`` and ``exception``), ``wait(futures, timeout)`` (the finished
ones, at least one unless the timeout passed) and ``close(kill=False)``.

No orphans: pool workers ask the kernel for SIGKILL when their parent dies
(``PR_SET_PDEATHSIG``; elsewhere a watchdog thread polls the parent), and ignore SIGINT, so a
Ctrl-C reaches the parent alone, which then kills them.  The workers of a local Dask cluster
are children of nanny objects that live in this process, and ``distributed`` ends a worker
process as soon as the pipe to its parent closes: a ``kill -9`` of the parent ends them too.
"""

from __future__ import annotations

import concurrent.futures as cf
import ctypes
import multiprocessing as mp
import os
import signal
import sys
import threading
import time

from pillar_xval.scenes import InputError, ToolError
from pillar_xval.threads import THREADS_ENV, limited, thread_count

EXECUTORS = ("serial", "pool", "dask")
PR_SET_PDEATHSIG = 1


def default_workers() -> int:
    """One local worker per thread the command may use
    (:func:`pillar_xval.threads.thread_count`), each on one thread: cases are independent,
    and a process per case scales where a solver's threads may not."""
    return thread_count()


def threads_per_worker(workers: int) -> int:
    """Threads each of ``workers`` local workers may use: the command's count shared out,
    so that workers times threads never exceeds it (at least one each: more workers than
    threads, which only an explicit ``--workers`` asks for, get one thread apiece)."""
    return max(1, thread_count() // max(1, int(workers)))


def _start_worker(parent_pid: int, threads: int) -> None:
    """Pool worker initializer: die with the parent (:func:`_die_with_parent`) and solve on
    ``threads`` threads (the count every solver reads, and the libraries loaded now)."""
    _die_with_parent(parent_pid)
    os.environ[THREADS_ENV] = str(threads)
    try:
        limited(threads).__enter__()  # for the worker's life
    except ImportError:
        pass


def _die_with_parent(parent_pid: int) -> None:
    """End this process when ``parent_pid`` ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the CLI's handler, if forked from it
    try:  # nor the CLI's signal watchdog's descriptor (its signals are not the parent's)
        signal.set_wakeup_fd(-1)
    except ValueError:
        pass
    armed = False
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent_pid:  # the parent died before the signal was armed
        os._exit(1)
    if not armed:
        def watch():
            while os.getppid() == parent_pid:
                time.sleep(1.0)
            os._exit(1)

        threading.Thread(target=watch, daemon=True, name="parent-watchdog").start()


def _noop() -> int:
    return os.getpid()


class SerialExecutor:
    """Cases run in this process, one at a time, when submitted."""

    name = "serial"
    capacity = 1

    def submit(self, fn, arg):
        future = cf.Future()
        try:
            future.set_result(fn(arg))
        except KeyboardInterrupt:
            raise
        except BaseException as exc:  # the engine sorts case errors from fatal ones
            future.set_exception(exc)
        return future

    def wait(self, futures, timeout=None):
        return {f for f in futures if f.done()}

    def close(self, kill: bool = False) -> None:
        pass


class PoolExecutor:
    """A local pool of ``workers`` forked processes, each on its share of the threads
    (:func:`threads_per_worker`)."""

    name = "pool"

    def __init__(self, workers: int):
        ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
        self.capacity = workers
        self.threads = threads_per_worker(workers)
        self._pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                            initializer=_start_worker,
                                            initargs=(os.getpid(), self.threads))
        # Start every worker now, from this thread (the death signal follows the thread that
        # forked) and before the engine holds any lock (a fork copies descriptors).
        for f in [self._pool.submit(_noop) for _ in range(workers)]:
            f.result()

    @property
    def pids(self) -> list[int]:
        return [p.pid for p in (self._pool._processes or {}).values()]

    def submit(self, fn, arg):
        try:
            return self._pool.submit(fn, arg)
        except cf.process.BrokenProcessPool as exc:
            raise ToolError(f"the process pool broke (a worker died: {exc})") from None

    def wait(self, futures, timeout=None):
        done, _ = cf.wait(futures, timeout=timeout, return_when=cf.FIRST_COMPLETED)
        return done

    def close(self, kill: bool = False) -> None:
        if kill:
            for pid in self.pids:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        self._pool.shutdown(wait=not kill, cancel_futures=True)


class DaskExecutor:
    """A Dask distributed cluster: ``address`` (``tcp://host:port``) or, without one, a local
    cluster of ``workers`` processes on 127.0.0.1, each running one case at a time on its
    share of the threads (:func:`threads_per_worker`; a remote cluster's workers count their
    own)."""

    name = "dask"

    def __init__(self, address: str | None, workers: int):
        try:
            import logging

            from distributed import Client, LocalCluster
        except ImportError as exc:
            raise ToolError(f"dask.distributed is not installed ({exc})") from None
        self._cluster = None
        try:
            if address:
                self._client = Client(address, timeout="20s")
            else:
                self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                             processes=True, host="127.0.0.1",
                                             dashboard_address="127.0.0.1:0",
                                             silence_logs=logging.ERROR,
                                             env={THREADS_ENV: str(threads_per_worker(
                                                 workers))})
                self._client = Client(self._cluster)
        except (OSError, TimeoutError) as exc:
            raise ToolError(f"dask: cannot reach the scheduler {address or '(local)'}: "
                            f"{exc}") from None
        self.address = self._client.scheduler.address
        threads = sum(self._client.nthreads().values())
        self.capacity = max(1, threads or workers)

    def submit(self, fn, arg):
        return self._client.submit(fn, arg, pure=False)

    def wait(self, futures, timeout=None):
        from distributed import wait

        try:
            wait(list(futures), timeout=timeout, return_when="FIRST_COMPLETED")
        except TimeoutError:
            pass
        return {f for f in futures if f.done()}

    def close(self, kill: bool = False) -> None:
        try:
            self._client.close()
        finally:
            if self._cluster is not None:
                self._cluster.close()


def make_executor(executor: str = "pool", workers: int | None = None,
                  scheduler: str | None = None):
    """The executor the user named (``--executor``, ``--workers``, ``--scheduler``)."""
    if scheduler:
        executor = "dask"
    if executor not in EXECUTORS:
        raise InputError(f"--executor {executor!r}: allowed: {', '.join(EXECUTORS)}")
    if workers is not None and workers < 1:
        raise InputError(f"--workers {workers}: must be >= 1")
    n = workers or default_workers()
    if executor == "serial":
        return SerialExecutor()
    if executor == "pool":
        return SerialExecutor() if n == 1 else PoolExecutor(n)
    return DaskExecutor(scheduler, n)
