"""The engine: run a batch of cases into a folder, skipping finished ones, on any executor.

The parent process owns the folder: it checks the cache, takes a case's lock, hands the
computation to the executor, writes the record the moment the result comes back, and frees
the lock.  Workers only compute (:func:`compute_case`), so the same code serves a serial run,
a local pool and a Dask cluster whose workers share no file system with the parent.

A case whose lock another process holds is put aside and retried; once that process has
written it, it is read from the cache.  Two identical commands into one folder therefore
compute each case once between them, and a killed process leaves nothing half-written.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path

from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import InputError, ToolError
from pillar_xval.threads import cpu_count, thread_count

from ._case import Case, compute_case
from ._executors import EXECUTORS, default_workers, make_executor, threads_per_worker
from ._progress import Progress
from ._store import CaseStore

# Errors of one case that leave the other cases running: input the model refuses
# (InputError, ScopeError and SceneError are ValueErrors), a tool that failed underneath
# (ToolError is a RuntimeError), arithmetic and memory trouble.  They become the case's
# outcome; anything else stops the batch.
CASE_ERRORS = (ArithmeticError, MemoryError, RuntimeError, ValueError)
# How often a process waiting on cases held by another one looks again (s).
POLL_S = 0.2


@dataclass
class Outcome:
    """What became of one case: its result (computed or cached) or the error it raised."""

    case: Case
    result: ContactResult | None = None
    error: BaseException | None = None
    cached: bool = False
    timing: dict = field(default_factory=dict)
    files: dict[str, Path] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.error is None

    def field_arrays(self) -> dict:
        """The result's arrays kept by a case with ``fields=True`` (e.g. ``x_m``, ``y_m``,
        ``pressure_Pa`` of the pressure map), SI units; {} when none were kept."""
        path = self.files.get("fields.npz")
        if path is None:
            return {}
        import numpy as np

        with np.load(path) as data:
            return {name: data[name] for name in data.files}

    def unwrap(self) -> ContactResult:
        """The result, or the case's error raised."""
        if self.error is not None:
            raise self.error
        return self.result


def max_workers() -> int:
    """Local processes beyond 4 per CPU this process may use only slow a study down (and may
    exhaust memory)."""
    return 4 * cpu_count()


def _check_executor(executor: str | None, workers: int | None, scheduler: str | None) -> None:
    """Refuse executor options that contradict each other, instead of one silently winning."""
    if executor is not None and executor not in EXECUTORS:
        raise InputError(f"--executor {executor!r}: allowed: {', '.join(EXECUTORS)}")
    if scheduler and executor not in (None, "dask"):
        raise InputError(f"--scheduler {scheduler}: sends cases to a Dask cluster, but "
                         f"--executor {executor} would run them here; drop one of the two")
    if workers is None:
        return
    if isinstance(workers, bool) or not isinstance(workers, int) or \
            not 1 <= workers <= max_workers():
        raise InputError(f"--workers {workers!r}: allowed range is [1, {max_workers()}] "
                         f"(4 per CPU this process may use)")
    if executor == "serial":
        raise InputError(f"--workers {workers}: --executor serial runs every case in this "
                         "process; workers are for --executor pool or dask")
    if scheduler:
        raise InputError(f"--workers {workers}: the Dask scheduler {scheduler} has its own "
                         "workers; start more of them there")


class Engine:
    """Runs cases (see :meth:`run`) on the executor the user chose.

    Parameters
    ----------
    executor : {"serial", "pool", "dask"}
        Where cases run: this process, a pool of local processes, or a Dask cluster.  The
        CLI's default is ``pool``; a library call defaults to ``serial``.
    workers : int, optional
        Pool processes, or the processes of a local Dask cluster (default: one per thread
        the command may use, :func:`pillar_xval.threads.thread_count`; each gets its share of
        the threads).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:port``); implies ``dask``.
    fresh : bool
        Recompute every case once in this engine's life, ignoring the cache.
    label : str
        Prefix of progress lines.
    quiet : bool
        No progress output.
    bar : bool, optional
        Force the progress bar on or off (default: on when stderr is a terminal).

    The executor starts on the first case that must be computed and lives until
    :meth:`close` (or the end of a ``with`` block), so a study that runs several batches
    starts one pool or one cluster.
    """

    def __init__(self, executor: str = "serial", workers: int | None = None,
                 scheduler: str | None = None, fresh: bool = False, label: str = "",
                 quiet: bool = False, bar: bool | None = None):
        _check_executor(executor, workers, scheduler)
        self.executor_name = executor or ("dask" if scheduler else "pool")
        self.workers, self.scheduler = workers, scheduler
        self.fresh, self.label, self.quiet, self.bar = fresh, label, quiet, bar
        self._executor = None
        self._computed: set[str] = set()

    # --- life cycle ---
    def __enter__(self) -> "Engine":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(kill=exc_type is not None)

    def close(self, kill: bool = False) -> None:
        if self._executor is not None:
            self._executor.close(kill=kill)
            self._executor = None

    @property
    def executor(self):
        if self._executor is None:
            self._executor = make_executor(self.executor_name, self.workers, self.scheduler)
        return self._executor

    @property
    def parallel(self) -> int:
        """How many cases run at once here (a remote scheduler's own workers: unknown, 1)."""
        if self.executor_name == "serial" or self.scheduler:
            return 1
        return self.workers or default_workers()

    @property
    def threads(self) -> int | None:
        """Threads each case runs on: the command's (this process), a local worker's share
        (:func:`._executors.threads_per_worker`), None on a remote Dask cluster."""
        if self.scheduler:
            return None
        if self.executor_name == "serial":
            return thread_count()
        return threads_per_worker(self.workers or default_workers())

    def describe(self) -> str:
        if self.executor_name == "dask":
            return f"dask ({self.scheduler or 'local cluster'})"
        return self.executor_name

    # --- running ---
    def run_one(self, case: Case, folder, label: str | None = None) -> Outcome:
        return self.run([case], folder, label)[0]

    def run(self, cases: list[Case], folder, label: str | None = None) -> list[Outcome]:
        """Run ``cases`` into ``folder``; one :class:`Outcome` per case, in input order.

        Cases with equal keys are computed once.  A case that raises one of
        :data:`CASE_ERRORS` gets that error as its outcome; other exceptions (Ctrl-C, a broken
        pool) stop the batch, kill the workers and propagate.
        """
        store = CaseStore(folder)
        unique: dict[str, Case] = {}
        for case in cases:
            unique.setdefault(case.key, case)
        progress = Progress(len(unique), label or self.label, bar=self.bar, quiet=self.quiet)
        outcomes: dict[str, Outcome] = {}
        pending, deferred = deque(unique.values()), []
        inflight: dict = {}
        waiting_said = False
        try:
            while pending or inflight or deferred:
                while pending and len(inflight) < self._capacity():
                    case = pending.popleft()
                    started = self._start(case, store, progress, outcomes)
                    if started is None:
                        continue
                    if started is False:
                        deferred.append(case)
                        continue
                    inflight[started[0]] = (case, started[1])
                if inflight:
                    done = self.executor.wait(list(inflight), POLL_S if deferred else None)
                    for future in done:
                        case, lock = inflight.pop(future)
                        try:
                            outcomes[case.key] = self._finish(case, future, store, progress)
                        finally:
                            lock.release()
                elif deferred:
                    if not waiting_said:
                        progress.line(f"waiting for {len(deferred)} case(s) that another "
                                      "process is computing in this folder")
                        waiting_said = True
                    time.sleep(POLL_S)
                if deferred and not pending:
                    pending.extend(deferred)
                    deferred.clear()
        except BaseException:
            for _, lock in inflight.values():
                lock.release()
            self.close(kill=True)
            raise
        finally:
            progress.close()
        return [dataclasses.replace(outcomes[c.key], case=c) for c in cases]

    def _capacity(self) -> int:
        # A serial executor computes inside submit: no need to start anything to know that.
        workers = self.workers or default_workers()
        if self.executor_name == "serial" or (self.executor_name == "pool" and workers == 1):
            return 1
        return self.executor.capacity if self._executor is not None else workers

    def _use_cache(self, case: Case) -> bool:
        return not self.fresh or case.key in self._computed

    def _cached(self, case, store, progress, record) -> Outcome:
        progress.finish(case.describe(), "cached", computed=False)
        return Outcome(case, store.result_of(record), cached=True, timing=record["timing"],
                       files=store.companions(case, record))

    def _start(self, case: Case, store: CaseStore, progress: Progress, outcomes: dict):
        """None: settled from the cache; False: held by another process; else (future, lock)."""
        why = ""
        if self._use_cache(case):
            record, why = store.load(case)
            if record is not None:
                outcomes[case.key] = self._cached(case, store, progress, record)
                return None
        # Start the executor before holding any lock: a pool forks its workers, and a fork
        # copies the lock's descriptor into them.
        executor = self.executor
        lock = store.try_lock(case)
        if lock is None:
            return False
        if self._use_cache(case):  # another process may have finished it meanwhile
            record, why_now = store.load(case)
            if record is not None:
                lock.release()
                outcomes[case.key] = self._cached(case, store, progress, record)
                return None
            why = why or why_now
        if why:
            progress.line(f"{case.describe()}: cached record {why}; recomputing")
        try:
            store.journal("start", case, executor=self.executor_name)
            progress.started(case.describe())
            future = executor.submit(compute_case, case.spec())
        except BaseException:
            lock.release()
            raise
        return future, lock

    def _finish(self, case: Case, future, store: CaseStore, progress: Progress) -> Outcome:
        try:
            payload = future.result()
        except BrokenProcessPool as exc:
            raise ToolError(f"the process pool broke (a worker died: {exc})") from None
        except CASE_ERRORS as exc:
            store.journal("failed", case, error=f"{type(exc).__name__}: {exc}")
            # The verdicts of the reports (extremes' summary): a model's up-front refusal of
            # its input (InputError, ScopeError) is "refused", anything else an "error".
            verdict = "refused" if isinstance(exc, InputError) else "error"
            progress.finish(case.describe(), f"{verdict}: {exc}", computed=True)
            return Outcome(case, error=exc)
        try:
            record = store.save(case, payload)
        except OSError as exc:
            raise ToolError(f"cannot write case {case.key} to {store.folder}: {exc}") from None
        self._computed.add(case.key)
        store.journal("done", case, wall_time_s=payload["timing"]["wall_time_s"],
                      worker=payload.get("worker"))
        result = store.result_of(record)
        flag = "" if result.converged else "  (NOT CONVERGED)"
        progress.finish(case.describe(), f"done in {payload['timing']['wall_time_s']:.3g} s{flag}",
                        computed=True)
        return Outcome(case, result, timing=record["timing"],
                       files=store.companions(case, record))
