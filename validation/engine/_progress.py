"""Progress of a batch of cases: a bar with count, rate and ETA on a terminal (tqdm), one plain
line per event otherwise (CI logs, pipes)."""

from __future__ import annotations

import math
import sys
import time


def _eta(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


class Progress:
    """Counts finished cases (computed, cached or failed) out of ``total``.

    The rate and the ETA count computed cases only: cached ones cost nothing.
    """

    def __init__(self, total: int, label: str = "pillar-xval", stream=None, bar: bool | None = None,
                 quiet: bool = False):
        self.total, self.label = total, label or "pillar-xval"
        self.stream = stream or sys.stderr
        self.quiet = quiet
        self.finished = self.computed = 0
        self._t0 = time.perf_counter()
        if bar is None:
            bar = hasattr(self.stream, "isatty") and self.stream.isatty()
        self._bar = None
        if bar and not quiet and total > 0:
            from tqdm import tqdm

            self._bar = tqdm(total=total, desc=self.label, unit="case", file=self.stream,
                             dynamic_ncols=True, smoothing=0.1)

    def _rate(self) -> tuple[float | None, str]:
        elapsed = time.perf_counter() - self._t0
        if not self.computed or elapsed <= 0:
            return None, "ETA ?"
        rate = self.computed / elapsed
        return rate, f"ETA {_eta((self.total - self.finished) / rate)}"

    def line(self, text: str) -> None:
        if self.quiet:
            return
        if self._bar is not None:
            self._bar.write(f"[{self.label}] {text}", file=self.stream)
        else:
            write_line(self.stream, f"[{self.label}] {text}")

    def started(self, what: str) -> None:
        if self._bar is None:
            self.line(f"{what}: running ...")

    def finish(self, what: str, how: str, computed: bool) -> None:
        self.finished += 1
        self.computed += computed
        rate, eta = self._rate()
        if self._bar is not None:
            self._bar.update(1)
            self._bar.set_postfix_str(how[:40], refresh=True)  # the bar keeps its width
            return
        speed = "" if rate is None else f", {rate:.3g} case/s, {eta}"
        self.line(f"{self.finished}/{self.total} {what}: {how}{speed}")

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def write_line(stream, text: str) -> None:
    """One whole line in one write: the lines of pool workers that share a terminal or a
    pipe never break into each other (a pipe write up to 4 KiB is atomic)."""
    stream.write(text + "\n")
    stream.flush()


class SolveProgress:
    """Progress inside one long solve, for a model's ``progress`` callback.

    Models call it as ``progress(iteration, residual)`` (the FFT model, the constrained CG) or
    ``progress(text)`` (a phase: meshing, assembling, factorising, ...).  A solve shorter
    than ``after_s`` prints nothing; after that a line ``[label] what (elapsed)`` comes on a
    change of phase (at most one a second) and every ``every_s`` seconds while nothing
    changes (a heartbeat thread, so a phase of minutes without callbacks still shows).  Use
    it as a context manager around the solve.
    """

    def __init__(self, label: str, stream=None, every_s: float = 5.0, after_s: float = 2.0):
        import threading

        self.label, self.stream = label, stream or sys.stderr
        self.every_s, self.after_s = every_s, after_s
        self._t0 = time.perf_counter()
        self._state, self._changed, self._last = "running", False, -math.inf
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, daemon=True, name="solve-progress")
        self.lines = 0

    def __enter__(self) -> "SolveProgress":
        self._t0 = time.perf_counter()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)

    def __call__(self, *args) -> None:
        if len(args) == 1:
            state = str(args[0])
        elif len(args) >= 2:
            state = f"iteration {args[0]}, residual {float(args[1]):.3g}"
        else:
            return
        with self._lock:
            phase = len(args) == 1
            self._changed = self._changed or phase
            self._state = state
        if phase:
            self._maybe_print()

    def _beat(self) -> None:
        while not self._stop.wait(0.25):
            self._maybe_print()

    def _maybe_print(self) -> None:
        now = time.perf_counter()
        with self._lock:
            elapsed = now - self._t0
            if elapsed < self.after_s:
                return
            due = now - self._last >= self.every_s or (self._changed and now - self._last >= 1.0)
            if not due:
                return
            self._last, self._changed, state = now, False, self._state
        write_line(self.stream, f"[{self.label}] {state} ({_eta(elapsed)})")
        self.lines += 1
