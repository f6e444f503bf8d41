"""Start-up time of the CLI: `pillar-xval --version` and `pillar-xval solve --help`, median
of 5 runs each in fresh processes, printed and written to startup.json.

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
RUNS = 5


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench-startup"))
    args = parser.parse_args(argv)
    rows = []
    for command in COMMANDS:
        times = []
        for _ in range(RUNS):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "validation.cli", *command], check=True,
                           capture_output=True)
            times.append(time.perf_counter() - t0)
        rows.append({"command": "pillar-xval " + " ".join(command),
                     "median_s": statistics.median(times), "runs_s": times})
        print(f"{rows[-1]['command']:<28} median {rows[-1]['median_s']:.3f} s of {RUNS}")
    args.out.mkdir(parents=True, exist_ok=True)
    doc = {"rows": rows, "load_average": os.getloadavg()}
    (args.out / "startup.json").write_text(json.dumps(doc, indent=2))
    print(f"written to {args.out / 'startup.json'} (load average {doc['load_average'][0]:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
