"""What a sweep's grid costs before anything is solved: the dry run's time on grids of 1e4 and
1e5 points (median of 3 fresh processes each), and the memory each axis value and each case
of a run hold (the figures behind ``validation.studies.sweep.grid.BYTES_PER_AXIS_VALUE`` and
``BYTES_PER_CASE``), printed and written to sweep.json.

    python -m validation.bench.sweep --out out/bench-sweep

Memory is Python's own allocations (``tracemalloc``'s peak over the step, divided by the
count): an axis of 10^6 log-spaced values with its repeated-value check; 2000 cases of a
lattice grid with the engine's outcome of each (a dense BEM result on paper-fig3-dense, 151
pillars in contact, read back from its record as a cached case is), their table rows and
the table written.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

RUNS = 3
DRY_RUN_POINTS = (10_000, 100_000)
AXIS_VALUES = 1_000_000
CASES = 2_000
SPEC = """scene = "paper-fig3-sparse"
on_invalid = "skip"
[grid]
"load.indentation_um" = {{ log = [0.05, 1.9], num = {num} }}
[[models]]
name = "bem"
"""


def dry_run_seconds(points: int, folder: Path) -> list[float]:
    spec = folder / f"grid-{points}.toml"
    spec.write_text(SPEC.format(num=points))
    times = []
    for _ in range(RUNS):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "validation.cli", "sweep", str(spec), "--dry-run",
                        "--out", str(folder / "o")], check=True, capture_output=True)
        times.append(time.perf_counter() - t0)
    return times


def _peak(step) -> int:
    tracemalloc.start()
    try:
        keep = step()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    del keep
    return peak


def bytes_per_axis_value() -> float:
    from validation.studies.sweep import crossed, log

    return _peak(lambda: crossed("load.indentation_um", log(0.05, 1.9, AXIS_VALUES))) \
        / AXIS_VALUES


def bytes_per_case(folder: Path) -> float:
    from bem_solver import solve_dense
    from pillar_xval.outcome import ContactResult
    from pillar_xval.scenes import load_scene
    from validation.engine import Outcome
    from validation.studies.sweep import ModelSpec, Sweep, crossed, linear, table_rows, \
        write_table

    record = solve_dense(load_scene("paper-fig3-dense"), 5).to_dict()
    sweep = Sweep("paper-fig3-sparse", axes=(crossed("load.indentation_um",
                                                      linear(0.1, 1.0, CASES)),),
                  models=(ModelSpec("bem", {"elements_per_diameter": 5}),))

    def run():
        cases, _ = sweep.cases()
        timing = {"wall_time_s": 0.5, "wall_times_s": [0.5], "peak_memory_MB": 10.0}
        pairs = [(c, Outcome(c.case, ContactResult.from_dict(json.loads(json.dumps(record))),
                             cached=True, timing=dict(timing))) for c in cases]
        rows = table_rows(sweep, pairs)
        write_table(rows, folder / "table", "bench")
        return pairs, rows

    return _peak(run) / CASES


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench-sweep"))
    args = parser.parse_args(argv)
    doc = {"load_average_start": os.getloadavg(), "dry_run": []}
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        for points in DRY_RUN_POINTS:
            times = dry_run_seconds(points, Path(tmp))
            doc["dry_run"].append({"points": points, "median_s": statistics.median(times),
                                   "runs_s": times})
            print(f"dry run of {points:>7,} points: median {statistics.median(times):.2f} s "
                  f"of {RUNS} ({', '.join(f'{t:.2f}' for t in times)})")
        doc["bytes_per_axis_value"] = bytes_per_axis_value()
        print(f"an axis of {AXIS_VALUES:,} values: {doc['bytes_per_axis_value']:.0f} bytes "
              "per value (peak)")
        doc["bytes_per_case"] = bytes_per_case(Path(tmp))
        print(f"a run of {CASES:,} lattice cases: {doc['bytes_per_case'] / 1e3:.1f} kB per "
              "case (peak: cases, outcomes, rows, table)")
    doc["load_average_end"] = os.getloadavg()
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "sweep.json").write_text(json.dumps(doc, indent=2))
    print(f"written to {args.out / 'sweep.json'} (load average "
          f"{doc['load_average_start'][0]:.2f} -> {doc['load_average_end'][0]:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
