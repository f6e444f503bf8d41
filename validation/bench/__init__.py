"""Benchmarks (speed and memory), run by the Makefile targets; never imported by the CLI."""

from __future__ import annotations

import json
import statistics
import time
from pathlib import Path


def median_time(fn, repeats: int):
    """(median wall time in s of ``repeats`` calls of ``fn``, the last call's result)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def write_record(out: Path, name: str, meta: dict, rows: list, table: str) -> None:
    """``{meta, rows, table}`` as JSON in ``out``/``name``, atomically (no NaN or inf)."""
    from pillar_xval.outcome import write_atomic

    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / name, json.dumps({"meta": meta, "rows": rows, "table": table},
                                        indent=2, allow_nan=False))
