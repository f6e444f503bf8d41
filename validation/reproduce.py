"""Byte-for-byte reproduction against another revision:
``python -m validation.reproduce --against REV --out DIR [--full]``.

The same commands run twice, each in fresh interpreters whose ``PYTHONPATH`` is one side's
code: this checkout and ``REV`` (a git revision of this repository, extracted with
``git archive``).  They regenerate

- the paper's figures' data: ``pillar-xval figures`` (``--quick`` unless ``--full``, which
  takes minutes): fig3.csv ... fig8.csv, claims.csv, the PNGs, figures.md, figures.json;
- a lattice study and the planner's lattice tables from it: ``pillar-xval lattice --quick``
  on :data:`LATTICE_ARGS` (Hooke and elastic BEMs and fem-3d, about a minute), then
  ``pillar-xval calibrate --lattice lattice.json --lattice-only`` (error_models.json).

Each side builds the elastic pillar's compliance afresh (its own ``PILLAR_XVAL_CACHE``), so
that code is compared too.  Every file the commands write (but the engine's case caches) must
be the same byte for byte, except what measures the run itself: the JSON keys in
:data:`VOLATILE_KEYS`, the durations in timing.json and figures.md's timing line
(:data:`VOLATILE_LINE`) are left out of the comparison of those files, and the report names
each file that differs.  Exit 0 when
everything reproduces, 1 otherwise, 2 for a revision git does not know.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# One scene per pillar regime of the lattice tables: a Phi = 0.1 and a Phi = 0.2 lattice at
# E_s = E_l, soft and stiff pillars, one at the paper's E_s = E_p.
LATTICE_ARGS = ("--quick", "--surface-fractions", "0.1,0.2", "--ratios", "1,10",
                "--paper-scenes", "0.2:10")
# What records the run rather than its result: wall times and timings, where the files went,
# when an entry was added.
VOLATILE_KEYS = frozenset({"wall_time_s", "timing", "paths", "file", "added", "created"})
# A file that times the run: its durations (keys ending in _s) are left out too.
TIMING_FILE = "timing.json"
VOLATILE_LINE = re.compile(r" in [0-9.]+ s on ")


def commands(full: bool) -> list[tuple[str, list[str]]]:
    """The (name, pillar-xval arguments) run on each side, in order, output folders relative
    to the side's folder."""
    return [("figures", ["figures", *([] if full else ["--quick"]), "--out", "figures"]),
            ("lattice", ["lattice", *LATTICE_ARGS, "--out", "lattice"]),
            ("planner", ["calibrate", "--lattice", "lattice/lattice.json", "--lattice-only",
                         "--out", "planner"])]


def _drop_volatile(value, durations: bool = False):
    if isinstance(value, dict):
        return {k: _drop_volatile(v, durations) for k, v in value.items()
                if k not in VOLATILE_KEYS and not (durations and k.endswith("_s"))}
    if isinstance(value, list):
        return [_drop_volatile(v, durations) for v in value]
    return value


def comparable(path: Path) -> bytes:
    """The bytes of ``path`` that must reproduce: all of them, but a JSON document's
    :data:`VOLATILE_KEYS` (and the durations of :data:`TIMING_FILE`) and a Markdown file's
    timing lines."""
    data = path.read_bytes()
    if path.suffix == ".json":
        kept = _drop_volatile(json.loads(data), durations=path.name == TIMING_FILE)
        return json.dumps(kept, sort_keys=True).encode()
    if path.suffix == ".md":
        return b"\n".join(line for line in data.split(b"\n")
                          if not VOLATILE_LINE.search(line.decode(errors="replace")))
    return data


def outputs(folder: Path) -> set[Path]:
    """The files under ``folder`` that a comparison reads (not the engine's case caches)."""
    return {p.relative_to(folder) for p in folder.rglob("*")
            if p.is_file() and "cases" not in p.relative_to(folder).parts}


def compare(a: Path, b: Path) -> dict:
    """``same``, ``differ`` and ``missing`` (on one side only): relative paths, sorted."""
    fa, fb = outputs(a), outputs(b)
    both = sorted(fa & fb)
    differ = [str(p) for p in both if comparable(a / p) != comparable(b / p)]
    return {"same": [str(p) for p in both if str(p) not in differ], "differ": differ,
            "missing": sorted(str(p) for p in fa ^ fb)}


def extract(rev: str, dest: Path) -> None:
    """``rev``'s tree of this repository into ``dest``; ValueError when git does not know it."""
    try:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev],
                                 capture_output=True)
    except OSError as exc:
        raise ValueError(f"--against {rev!r}: cannot run git ({exc})") from None
    if archive.returncode != 0:
        raise ValueError(f"--against {rev!r}: {archive.stderr.decode().strip()}")
    dest.mkdir(parents=True)
    tar_path = dest.parent / f"{dest.name}.tar"
    tar_path.write_bytes(archive.stdout)
    with tarfile.open(tar_path) as tar:
        tar.extractall(dest, filter="data")
    tar_path.unlink()


def run_side(code: Path, out: Path, full: bool) -> None:
    """Every command of :func:`commands` with ``code`` first on the path, in ``out``."""
    out.mkdir(parents=True)
    env = {**os.environ, "PYTHONPATH": str(code),
           "PILLAR_XVAL_CACHE": str(out.parent / f"cache-{out.name}")}
    for name, args in commands(full):
        print(f"  {out.name}: pillar-xval {' '.join(args)}", flush=True)
        done = subprocess.run([sys.executable, "-m", "validation.cli", *args,
                               "--executor", "serial"],
                              cwd=out, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"{out.name}: {name} failed (exit {done.returncode}): "
                               f"{done.stderr.strip()[-400:]}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", required=True, help="git revision to reproduce (main, a hash)")
    ap.add_argument("--out", type=Path, default=None,
                    help="folder for both sides' outputs and reproduce.json (default: a "
                         "temporary one, removed)")
    ap.add_argument("--full", action="store_true",
                    help="the full figures (minutes) instead of --quick")
    args = ap.parse_args(argv)
    if args.out is not None and args.out.exists() and any(args.out.iterdir()):
        print(f"reproduce: --out {args.out}: not empty (both sides write there)",
              file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="reproduce-") as tmp:
        base = args.out or Path(tmp)
        try:
            extract(args.against, base / "code-against")
        except ValueError as exc:
            print(f"reproduce: {exc}", file=sys.stderr)
            return 2
        for side, code in (("this", ROOT), ("against", base / "code-against")):
            try:
                run_side(code, base / side, args.full)
            except RuntimeError as exc:
                print(f"reproduce: {exc}", file=sys.stderr)
                return 1
        found = compare(base / "this", base / "against")
        found.update(against=args.against, full=args.full,
                     commands=[" ".join(a) for _, a in commands(args.full)])
        (base / "reproduce.json").write_text(json.dumps(found, indent=1))
    print(f"{len(found['same'])} files reproduce byte for byte against {args.against}; "
          f"{len(found['differ'])} differ, {len(found['missing'])} on one side only")
    for key in ("differ", "missing"):
        for p in found[key]:
            print(f"  {key}: {p}")
    return 0 if not found["differ"] and not found["missing"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
