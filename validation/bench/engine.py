"""Benchmark of the study engine: ``python -m validation.bench.engine --out DIR``
(``make bench-engine``).

1. Resume: a sweep runs on the local pool and is killed (SIGKILL) once a third of its cases
   are finished; a rerun completes it.  Counted from the case folder's journal: cases lost
   (finished before the kill but computed again) and repeated (computed twice) must be 0.
   The killed + resumed wall time is set beside one uninterrupted run.
2. Dask: the same sweep on a scheduler and two workers started as separate processes
   (``dask scheduler`` / ``dask worker``, loopback 127.0.0.1 only) gives the same table as
   the local pool, apart from the measured columns (wall time, memory).

Each sweep is a subprocess of ``pillar-xval sweep``, as a user runs it.  Writes
bench_engine.json and prints a summary.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

from pillar_xval.outcome import write_atomic
from validation.engine import read_journal

# Measured columns: they differ from run to run, the results do not.
VOLATILE = ("wall_time_s", "peak_memory_MB")


def spec_text(cases: int, p: int) -> str:
    """A sweep of ``cases`` indentations on the dense Fig. 3 scene, dense BEM at P = ``p``."""
    return (f'name = "bench"\nscene = "paper-fig3-dense"\n[grid]\n'
            f'"load.indentation_um" = {{ linear = [0.1, 0.5], num = {cases} }}\n'
            f'[[models]]\nname = "bem"\nelements_per_diameter = {p}\n')


def sweep_cmd(spec: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "validation.cli", "sweep", str(spec), "--out", str(out),
            *extra]


def events(folder: Path, kind: str) -> Counter:
    return Counter(e["key"] for e in read_journal(folder) if e["event"] == kind)


def table(out: Path) -> list[dict]:
    with open(out / "bench.csv") as fh:
        return list(csv.DictReader(fh))


def results_only(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in VOLATILE} for r in rows]


def timed(cmd: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


@contextlib.contextmanager
def dask_processes(folder: Path, workers: int = 2, timeout: float = 60.0):
    """A Dask scheduler and ``workers`` single-threaded workers, each its own process on
    127.0.0.1; yields the scheduler's address and kills them all on exit."""
    dask = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")
    if dask is None:
        raise RuntimeError("the dask command is missing (pip install 'dask[distributed]')")
    folder = Path(folder).resolve()  # the processes run in it: relative paths would move
    info = folder / "scheduler.json"
    info.unlink(missing_ok=True)
    log = open(folder / "dask.log", "ab")  # noqa: SIM115  (closed below)
    quiet = {"cwd": folder, "stdout": log, "stderr": subprocess.STDOUT}
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(info)], **quiet)]
    try:
        end = time.monotonic() + timeout
        while not (info.exists() and info.stat().st_size > 0):
            if time.monotonic() > end or procs[0].poll() is not None:
                log.flush()
                tail = (folder / "dask.log").read_text(errors="replace")[-800:]
                raise RuntimeError(f"the dask scheduler did not start (exit "
                                   f"{procs[0].poll()}): {tail}")
            time.sleep(0.05)
        for _ in range(workers):
            procs.append(subprocess.Popen(
                [dask, "worker", "--scheduler-file", str(info), "--host", "127.0.0.1",
                 "--nthreads", "1", "--nworkers", "1", "--no-dashboard",
                 "--local-directory", str(folder / "dask-scratch")], **quiet))
        address = json.loads(info.read_text())["address"]
        from distributed import Client

        with Client(address, timeout=f"{timeout:.0f}s") as client:
            client.wait_for_workers(workers, timeout=timeout)
        yield address, procs
    finally:
        # A killed `dask worker` takes its worker process with it (the worker ends when the
        # pipe to its nanny closes).
        for p in procs[::-1]:
            p.kill()
            p.wait(15)
        log.close()


def bench_resume(folder: Path, cases: int, p: int, log) -> dict:
    spec = folder / "spec.toml"
    spec.write_text(spec_text(cases, p))
    clean = folder / "uninterrupted"
    t_clean = timed(sweep_cmd(spec, clean))
    out = folder / "killed"
    proc = subprocess.Popen(sweep_cmd(spec, out), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    start = time.perf_counter()
    while sum(events(out / "cases", "done").values()) < cases // 3:
        if proc.poll() is not None:
            raise RuntimeError("the sweep ended before it could be killed: use more cases")
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    t_killed = time.perf_counter() - start
    done_before = set(events(out / "cases", "done"))
    journal_before = len(read_journal(out / "cases"))
    t_rerun = timed(sweep_cmd(spec, out))
    after = read_journal(out / "cases")[journal_before:]
    computed_after = Counter(e["key"] for e in after if e["event"] == "done")
    done = events(out / "cases", "done")
    rows = table(out)
    row = {"cases": cases, "elements_per_diameter": p,
           "finished_before_kill": len(done_before),
           "computed_by_rerun": sum(computed_after.values()),
           "lost": len(done_before & set(computed_after)),
           "repeated": sum(n - 1 for n in done.values() if n > 1),
           "rows": len(rows), "failed_rows": sum(r["status"] != "ok" for r in rows),
           "same_table_as_uninterrupted": results_only(rows) == results_only(table(clean)),
           "uninterrupted_s": t_clean, "killed_after_s": t_killed, "rerun_s": t_rerun}
    log(f"resume: {row['finished_before_kill']}/{cases} finished when killed after "
        f"{t_killed:.1f} s; rerun computed {row['computed_by_rerun']} in {t_rerun:.1f} s; "
        f"lost {row['lost']}, repeated {row['repeated']}; same table as an uninterrupted run "
        f"({t_clean:.1f} s): {row['same_table_as_uninterrupted']}")
    return row


def bench_dask(folder: Path, cases: int, p: int, log) -> dict:
    spec = folder / "spec.toml"
    spec.write_text(spec_text(cases, p))
    t_pool = timed(sweep_cmd(spec, folder / "pool", "--executor", "pool", "--workers", "2"))
    with dask_processes(folder) as (address, _):
        t_dask = timed(sweep_cmd(spec, folder / "dask", "--scheduler", address))
    workers = {e["worker"]["pid"] for e in read_journal(folder / "dask" / "cases")
               if e["event"] == "done"}
    same = results_only(table(folder / "pool")) == results_only(table(folder / "dask"))
    row = {"cases": cases, "elements_per_diameter": p, "pool_s": t_pool, "dask_s": t_dask,
           "dask_workers_used": len(workers), "same_table": same}
    log(f"dask: {cases} cases on a scheduler + 2 worker processes in {t_dask:.1f} s "
        f"({len(workers)} workers used), local pool {t_pool:.1f} s; same table: {same}")
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation.bench.engine", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-engine"))
    ap.add_argument("--cases", type=int, default=30, help="sweep size (default 30)")
    ap.add_argument("--elements-per-diameter", type=int, default=7, metavar="P",
                    help="dense BEM resolution (default 7: ~0.2 s per case)")
    ap.add_argument("--repeats", type=int, default=3, help="runs of each benchmark (default 3)")
    args = ap.parse_args(argv)

    def log(msg):
        print(msg, flush=True)

    args.out.mkdir(parents=True, exist_ok=True)
    work = args.out / "work"
    resume, dask = [], []
    for i in range(args.repeats):
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir(parents=True)
        resume.append(bench_resume(work, args.cases, args.elements_per_diameter, log))
        dask.append(bench_dask(work, args.cases, args.elements_per_diameter, log))
    shutil.rmtree(work, ignore_errors=True)

    def median(rows, key):
        values = sorted(r[key] for r in rows)
        return values[len(values) // 2]

    report = {
        "benchmark": "study engine: resume after kill -9, Dask cluster vs local pool",
        "machine_note": "2 cores shared with other users: times are contended",
        "resume": resume, "dask": dask,
        "summary": {
            "lost_total": sum(r["lost"] for r in resume),
            "repeated_total": sum(r["repeated"] for r in resume),
            "resume_tables_match": all(r["same_table_as_uninterrupted"] for r in resume),
            "dask_tables_match": all(r["same_table"] for r in dask),
            "median_uninterrupted_s": median(resume, "uninterrupted_s"),
            "median_rerun_s": median(resume, "rerun_s"),
            "median_pool_s": median(dask, "pool_s"), "median_dask_s": median(dask, "dask_s")}}
    write_atomic(args.out / "bench_engine.json", json.dumps(report, indent=2) + "\n")
    s = report["summary"]
    log(f"summary over {args.repeats} runs: lost {s['lost_total']}, repeated "
        f"{s['repeated_total']}, resumed tables match: {s['resume_tables_match']}, Dask tables "
        f"match: {s['dask_tables_match']}; medians: uninterrupted {s['median_uninterrupted_s']:.1f}"
        f" s, rerun after kill {s['median_rerun_s']:.1f} s, pool {s['median_pool_s']:.1f} s, "
        f"Dask {s['median_dask_s']:.1f} s")
    log(f"written {args.out / 'bench_engine.json'}")
    ok = (s["lost_total"] == 0 and s["repeated_total"] == 0 and s["resume_tables_match"]
          and s["dask_tables_match"])
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
