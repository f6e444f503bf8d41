"""Progress of a batch of cases: a bar with count, rate and ETA on a terminal (tqdm), one plain
line per event otherwise (CI logs, pipes)."""

from __future__ import annotations

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
            print(f"[{self.label}] {text}", file=self.stream, flush=True)

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
