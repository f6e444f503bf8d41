"""Start-up time of the CLI: `pillar-xval --version` and `pillar-xval solve --help`, and what
importing each library the toolkit defers would add to them, median of 5 runs each in fresh
processes (interleaved: each round runs every command once), printed and written to
startup.json.

    python -m validation.bench.startup --out out/bench-startup
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

COMMANDS = (("--version",), ("solve", "--help"))
# The libraries imported inside the functions that use them: at module level, every command
# (and --help, which builds every command's parser) would pay for them.
DEFERRED = ("scipy.sparse.linalg", "matplotlib.pyplot", "skfem", "gmsh", "pyvista")
RUNS = 5


def _runs() -> dict[str, list[str]]:
    runs = {"pillar-xval " + " ".join(c): [sys.executable, "-m", "validation.cli", *c]
            for c in COMMANDS}
    runs["python -c pass"] = [sys.executable, "-c", "pass"]
    runs |= {f"import {m}": [sys.executable, "-c", f"import {m}"] for m in DEFERRED}
    return runs


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench-startup"))
    args = parser.parse_args(argv)
    runs = _runs()
    times: dict[str, list[float]] = {name: [] for name in runs}
    env = {**os.environ, "MPLBACKEND": "Agg"}
    for _ in range(RUNS):
        for name, command in runs.items():
            t0 = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True, env=env)
            times[name].append(time.perf_counter() - t0)
    rows = [{"command": name, "median_s": statistics.median(t), "runs_s": t}
            for name, t in times.items()]
    for row in rows:
        print(f"{row['command']:<28} median {row['median_s']:.3f} s of {RUNS}")
    args.out.mkdir(parents=True, exist_ok=True)
    doc = {"rows": rows, "load_average": os.getloadavg()}
    (args.out / "startup.json").write_text(json.dumps(doc, indent=2))
    print(f"written to {args.out / 'startup.json'} (load average {doc['load_average'][0]:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
