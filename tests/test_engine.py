"""The study engine: cache keys, records checked on read, resume after ``kill -9``, two
processes on one folder, no orphan workers, and the Dask executor on a local cluster.

Real computations use the dense BEM at small P (a few hundredths of a second to a few tenths
per case).  Computations are counted from the folder's journal: one ``done`` line per case
computed, written by the process that computed it.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest

from pillar_xval.scenes import load_scene
from validation.engine import (Case, CaseStore, Engine, Progress, case_key, code_version,
                               read_journal, source_digest)


# A subprocess that should be well into its sweep: a generous bound on a contended machine.
TIMEOUT_S = 120


def _done(folder) -> Counter:
    return Counter(e["key"] for e in read_journal(folder) if e["event"] == "done")


def _started(folder) -> Counter:
    return Counter(e["key"] for e in read_journal(folder) if e["event"] == "start")


# --- keys ----------------------------------------------------------------------------------
def test_key_is_stable_and_sensitive_to_what_is_computed():
    scene = load_scene("paper-fig3-sparse")
    opts = {"elements_per_diameter": 7, "cells": "covered"}
    key = case_key("bem", scene, opts)
    assert len(key) == 16 and int(key, 16) >= 0
    # insensitive to the scene's name and to the order of the options
    assert case_key("bem", scene.replace(name="renamed"), opts) == key
    assert case_key("bem", scene, dict(reversed(list(opts.items())))) == key
    # the same in another interpreter (no per-process hash seed in the key)
    code = ("from pillar_xval.scenes import load_scene; from validation.engine import case_key; "
            "print(case_key('bem', load_scene('paper-fig3-sparse'), "
            "{'cells': 'covered', 'elements_per_diameter': 7}))")
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True, env={**os.environ, "PYTHONHASHSEED": "123"})
    assert other.stdout.strip() == key
    # sensitive to the scene's physics, the model, each option and the code version
    assert case_key("bem", load_scene("paper-fig3-sparse", ["load.indentation_um=0.31"]),
                    opts) != key
    assert case_key("bem", load_scene("paper-fig3-sparse", ["pillars.nu=0.4"]), opts) != key
    assert case_key("bem-fft", scene, opts) != key
    assert case_key("bem", scene, {**opts, "elements_per_diameter": 9}) != key
    assert case_key("bem", scene, {**opts, "contact": "paper"}) != key
    assert case_key("bem", scene, opts, version=code_version() + "x") != key
    assert code_version().startswith(__import__("pillar_xval.outcome", fromlist=["_"]).package_version())


def test_source_digest_follows_every_source_edit(tmp_path):
    root = tmp_path / "pkg"
    (root / "sub").mkdir(parents=True)
    (root / "a.py").write_text("x = 1\n")
    (root / "sub" / "b.toml").write_text("k = 2\n")
    (root / "notes.txt").write_text("not source")
    first = source_digest({"pkg": root})
    assert source_digest({"pkg": root}) == first
    (root / "notes.txt").write_text("still not source")
    assert source_digest({"pkg": root}) == first
    (root / "sub" / "b.toml").write_text("k = 3\n")
    edited = source_digest({"pkg": root})
    assert edited != first
    (root / "c.py").write_text("")
    assert source_digest({"pkg": root}) != edited
    assert source_digest({"pkg": None}) != source_digest({"other": None})


# --- records ---------------------------------------------------------------------------------
def _bem_case(p=5, **kw):
    return Case("bem", load_scene("paper-fig3-sparse"), {"elements_per_diameter": p}, **kw)


def _corrupt_json(text):
    return text[: len(text) // 2]


def _set(path_in_record, value):
    def edit(text):
        record = json.loads(text)
        node = record
        for k in path_in_record[:-1]:
            node = node[k]
        node[path_in_record[-1]] = value(node[path_in_record[-1]]) if callable(value) else value
        return json.dumps(record)
    return edit


def _nan(text):
    record = json.loads(text)
    record["result"]["centre_pressure_Pa"] = "NAN_HERE"
    return json.dumps(record).replace('"NAN_HERE"', "NaN")


def _inf(text):
    record = json.loads(text)
    record["result"]["pillar_forces"][0]["force_N"] = "INF_HERE"
    return json.dumps(record).replace('"INF_HERE"', "Infinity")


def _doubled(text):
    record = json.loads(text)
    for pf in record["result"]["pillar_forces"]:
        pf["force_N"] *= 2
    return json.dumps(record)


@pytest.mark.parametrize("corrupt, why", [
    (_corrupt_json, "unreadable"),
    (lambda t: "", "unreadable"),
    (_set(["key"], "0123456789abcdef"), "key"),
    (_set(["code_version"], "0.0.0+src.000000000000"), "code version"),
    (_set(["case", "model"], "bem-fft"), "model"),
    (_nan, "unreadable"),
    (_inf, "unreadable"),
    (_doubled, "pillar and floor forces sum"),
    (_set(["result", "total_force_N"], lambda f: 2 * f), "pillar and floor forces sum"),
    (_set(["result"], {"model": "bem"}), "does not parse"),
    (_set(["timing"], None), "timing"),
    (_set(["case"], 5), "malformed"),
    (_set(["files"], {"fields.vtu": 3}), "companion"),
    (lambda t: "[1, 2]", "not a case record"),
    (_set(["result", "centre_pressure_Pa"], lambda p: 1.1 * p), "digest"),
    (_set(["result", "contact_radius_m"], lambda a: 3 * a), "digest"),
    (_set(["timing", "wall_time_s"], lambda t: t + 1.0), "digest"),
])
def test_corrupt_record_is_recomputed(tmp_path, corrupt, why, capsys):
    case = _bem_case()
    first = Engine("serial").run_one(case, tmp_path)
    assert not first.cached and first.ok
    path = CaseStore(tmp_path).record_path(case)
    path.write_text(corrupt(path.read_text()))
    record, reason = CaseStore(tmp_path).load(case)
    assert record is None and why in reason
    again = Engine("serial").run_one(case, tmp_path)
    assert not again.cached
    assert again.result.total_force_N == first.result.total_force_N  # deterministic solver
    assert "recomputing" in capsys.readouterr().err
    assert _done(tmp_path)[case.key] == 2
    assert Engine("serial").run_one(case, tmp_path).cached  # the rewritten record is good


def _vtu_case():
    return Case("fem-axisym", load_scene("single-pillar"), {"mesh_size": 1.0}, vtu=True)


@pytest.mark.parametrize("damage", ["missing", "truncated", "garbage-same-size"])
def test_damaged_companion_vtu_is_recomputed(fakes, tmp_path, damage):
    case = _vtu_case()
    first = Engine("serial").run_one(case, tmp_path)
    vtu = first.files["fields.vtu"]
    assert vtu.stat().st_size > 0
    data = vtu.read_bytes()
    if damage == "missing":
        vtu.unlink()
    elif damage == "truncated":
        vtu.write_bytes(data[: len(data) // 2])
    else:
        vtu.write_bytes(b"\0" * len(data))
    record, reason = CaseStore(tmp_path).load(case)
    assert record is None and "fields.vtu" in reason
    fakes.clear()
    again = Engine("serial").run_one(case, tmp_path)
    assert not again.cached and fakes == [("fem", 1.0)]
    assert again.files["fields.vtu"].read_bytes() == data


def test_a_case_asking_for_the_vtu_recomputes_one_cached_without(fakes, tmp_path):
    plain = Case("fem-axisym", load_scene("single-pillar"), {"mesh_size": 1.0})
    Engine("serial").run_one(plain, tmp_path)
    assert _vtu_case().key == plain.key  # same computation, the VTU is a by-product
    with_vtu = Engine("serial").run_one(_vtu_case(), tmp_path)
    assert not with_vtu.cached and "fields.vtu" in with_vtu.files
    assert Engine("serial").run_one(plain, tmp_path).cached  # and the VTU does not hurt


def test_result_arrays_are_kept_on_request(tmp_path):
    plain = Engine("serial").run_one(_bem_case(), tmp_path)
    assert plain.field_arrays() == {}
    kept = Engine("serial").run_one(_bem_case(fields=True), tmp_path)
    assert not kept.cached  # the cached record had no arrays
    arrays = kept.field_arrays()
    # the kept map carries the result: the element forces of the D6 orbits, each counted
    # weight times, sum to the total force
    total = (arrays["force_N"] * arrays["weight"]).sum()
    assert total == pytest.approx(plain.result.total_force_N, rel=1e-12)
    assert arrays["pressure_Pa"].shape == arrays["x_m"].shape
    npz = kept.files["fields.npz"]
    npz.write_bytes(npz.read_bytes()[:100])
    record, reason = CaseStore(tmp_path).load(_bem_case(fields=True))
    assert record is None and "fields.npz" in reason
    again = Engine("serial").run_one(_bem_case(fields=True), tmp_path)
    assert not again.cached
    assert (again.field_arrays()["force_N"] == arrays["force_N"]).all()


def test_more_timing_repeats_recompute_fewer_do_not(tmp_path):
    once = Engine("serial").run_one(_bem_case(repeats=1), tmp_path)
    assert once.timing["repeats"] == 1
    thrice = Engine("serial").run_one(_bem_case(repeats=3), tmp_path)
    assert not thrice.cached and len(thrice.timing["wall_times_s"]) == 3
    assert Engine("serial").run_one(_bem_case(repeats=2), tmp_path).cached
    assert thrice.timing["wall_time_s"] == sorted(thrice.timing["wall_times_s"])[1]
    assert thrice.timing["peak_memory_MB"] >= 0


def test_failed_case_is_an_outcome_and_not_cached(tmp_path):
    bad = Case("bem", load_scene("paper-fig3-sparse"), {"elements_per_diameter": 0})
    good = _bem_case()
    out = Engine("serial", quiet=True).run([bad, good, good], tmp_path)
    assert not out[0].ok and isinstance(out[0].error, ValueError)
    assert out[1].ok and out[2].result is out[1].result  # equal keys computed once
    assert _done(tmp_path) == Counter({good.key: 1})
    assert [e["event"] for e in read_journal(tmp_path)].count("failed") == 1


def test_fresh_recomputes_once_per_engine(tmp_path):
    Engine("serial").run_one(_bem_case(), tmp_path)
    engine = Engine("serial", fresh=True)
    assert not engine.run_one(_bem_case(), tmp_path).cached
    assert engine.run_one(_bem_case(), tmp_path).cached


def test_progress_plain_lines_have_count_rate_and_eta(tmp_path):
    import io

    stream = io.StringIO()
    progress = Progress(3, "demo", stream=stream)
    progress.finish("a", "cached", computed=False)
    progress.finish("b", "done in 0.1 s", computed=True)
    lines = stream.getvalue().splitlines()
    assert lines[0] == "[demo] 1/3 a: cached"
    assert lines[1].startswith("[demo] 2/3 b: done in 0.1 s, ") and "case/s, ETA" in lines[1]
    bar = io.StringIO()
    progress = Progress(2, "demo", stream=bar, bar=True)
    progress.finish("a", "done", computed=True)
    progress.close()
    assert "1/2" in bar.getvalue() and "case/s" in bar.getvalue()


# --- processes -------------------------------------------------------------------------------
def _spec(folder: Path, n: int, p: int = 5, scene: str = "paper-fig3-dense") -> Path:
    """A sweep of ``n`` indentations with the dense BEM at P = ``p`` (Hooke pillars: the
    engine's tests need no pillar compliance built)."""
    spec = folder / "spec.toml"
    spec.write_text(f'name = "t"\nscene = "{scene}"\n'
                    f'[grid]\n"load.indentation_um" = {{ linear = [0.1, 0.5], num = {n} }}\n'
                    f'[[models]]\nname = "bem"\nelements_per_diameter = {p}\n'
                    'pillars = "hooke"\n')
    return spec


def _sweep_cmd(spec: Path, out: Path, *extra) -> list[str]:
    return [sys.executable, "-m", "validation.cli", "sweep", str(spec), "--out", str(out),
            *extra]


def _alive(pid: int) -> bool:
    """Running (a zombie, dead but not yet reaped by its new parent, does not count)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False


def _wait_for(predicate, timeout=TIMEOUT_S, step=0.02):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(step)
    return False


def _rows(out: Path) -> list[dict]:
    import csv

    with open(out / "t.csv") as fh:
        return list(csv.DictReader(fh))


def test_kill_9_mid_sweep_loses_nothing_repeats_nothing_leaves_no_orphan(tmp_path):
    spec, out = _spec(tmp_path, 16), tmp_path / "out"
    cases = out / "cases"
    proc = subprocess.Popen(_sweep_cmd(spec, out, "--workers", "2"),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert _wait_for(lambda: sum(_done(cases).values()) >= 3)
        assert proc.poll() is None, "the sweep ended before it could be killed"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    first = read_journal(cases)
    done_first = {e["key"] for e in first if e["event"] == "done"}
    workers = {e["worker"]["pid"] for e in first if e["event"] == "done"}
    assert workers and proc.pid not in workers  # the cases ran in pool workers
    assert _wait_for(lambda: not any(_alive(pid) for pid in workers), timeout=10), \
        "pool workers outlived their killed parent"
    assert len(done_first) < 16
    # the rerun computes exactly what is missing
    rerun = subprocess.run(_sweep_cmd(spec, out, "--workers", "2"), capture_output=True,
                           text=True, timeout=TIMEOUT_S)
    assert rerun.returncode == 0, rerun.stderr
    second = read_journal(cases)[len(first):]
    started_second = {e["key"] for e in second if e["event"] == "start"}
    assert not started_second & done_first  # nothing repeated
    rows = _rows(out)
    assert len(rows) == 16 and all(r["status"] == "ok" for r in rows)  # nothing lost
    done = _done(cases)
    # every case computed once (a case killed after its record was written but before its
    # journal line is read from the cache, never recomputed)
    assert set(done) <= {r["case_key"] for r in rows} and set(done.values()) == {1}
    assert len(done) >= 15


def test_two_processes_on_one_folder_compute_each_case_once(tmp_path):
    spec, out = _spec(tmp_path, 10), tmp_path / "out"
    procs = [subprocess.Popen(_sweep_cmd(spec, out, "--workers", "2"), stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [p.communicate(timeout=TIMEOUT_S) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [r[1][-500:] for r in results]
    done = _done(out / "cases")
    assert len(done) == 10 and set(done.values()) == {1}
    assert len({e["pid"] for e in read_journal(out / "cases") if e["event"] == "done"}) == 2
    assert len(_rows(out)) == 10


def test_a_waiting_process_takes_over_a_case_whose_holder_died(tmp_path):
    """A lock is freed by the kernel when its holder dies: nothing stays locked."""
    case = _bem_case()
    holder = subprocess.Popen(
        [sys.executable, "-c",
         "import sys, time; from pillar_xval.scenes import load_scene; "
         "from validation.engine import Case, CaseStore; "
         "c = Case('bem', load_scene('paper-fig3-sparse'), {'elements_per_diameter': 5}); "
         f"lock = CaseStore({str(tmp_path)!r}).try_lock(c); print('locked', flush=True); "
         "time.sleep(60)"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert CaseStore(tmp_path).try_lock(case) is None
        os.kill(holder.pid, signal.SIGKILL)
        holder.wait(10)
    finally:
        if holder.poll() is None:
            holder.kill()
    out = Engine("serial", quiet=True).run_one(case, tmp_path)
    assert out.ok and not out.cached


@pytest.fixture
def dask_cluster(tmp_path):
    """A scheduler and two single-threaded workers, separate processes on 127.0.0.1."""
    from validation.bench.engine import dask_processes

    with dask_processes(tmp_path) as (address, procs):
        family = {q for p in procs for q in _descendants(p.pid)}
        yield address
    assert _wait_for(lambda: not any(_alive(q) for q in family), timeout=15), \
        "dask processes outlived the test"


def _descendants(pid: int) -> set[int]:
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry.name))
    out, todo = set(), [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.add(c)
            todo.append(c)
    return out


VOLATILE = {"wall_time_s", "peak_memory_MB"}  # measurements, not results


def test_dask_cluster_gives_the_serial_table(tmp_path, dask_cluster):
    from validation.studies.sweep import Sweep, run_sweep, write_table

    spec = _spec(tmp_path, 6, p=5, scene="paper-fig3-sparse")
    sweep = Sweep.from_toml(spec)
    write_table(run_sweep(sweep, tmp_path / "serial", engine=Engine("serial", quiet=True)),
                tmp_path / "serial", "t")
    dask = subprocess.run(_sweep_cmd(spec, tmp_path / "dask", "--scheduler", dask_cluster),
                          capture_output=True, text=True, timeout=TIMEOUT_S)
    assert dask.returncode == 0, dask.stderr
    a, b = _rows(tmp_path / "serial"), _rows(tmp_path / "dask")
    assert [{k: v for k, v in r.items() if k not in VOLATILE} for r in a] == \
        [{k: v for k, v in r.items() if k not in VOLATILE} for r in b]
    journal = read_journal(tmp_path / "dask" / "cases")
    workers = {e["worker"]["pid"] for e in journal if e["event"] == "done"}
    parents = {e["pid"] for e in journal}
    assert workers and not workers & parents  # computed by the cluster's workers
    assert all(math.isfinite(float(r["total_force_N"])) for r in b)


def test_local_dask_cluster_gives_the_serial_results(tmp_path):
    """``--executor dask`` without an address: a local cluster on 127.0.0.1, closed after."""
    cases = [Case("bem", load_scene("paper-fig3-sparse", [f"load.indentation_um={z}"]),
                  {"elements_per_diameter": 3}) for z in (0.2, 0.3, 0.4)]
    serial = Engine("serial", quiet=True).run(cases, tmp_path / "serial")
    with Engine("dask", workers=2, quiet=True) as engine:
        dask = engine.run(cases, tmp_path / "dask")
        assert engine.executor.address.startswith("tcp://127.0.0.1:")
    assert [o.result.to_dict() | {"wall_time_s": 0} for o in dask] == \
        [o.result.to_dict() | {"wall_time_s": 0} for o in serial]
    assert not any(o.cached for o in dask)


def test_a_mixed_contact_is_read_back_from_the_cache(tmp_path):
    # The floor carries the part of the load the pillars do not: the record's check adds it
    # (without it every mixed case was computed again on each run).
    scene = load_scene("paper-fig3-sparse", ["lens.radius_mm=0.25", "pillars.height_um=1",
                                             "load.indentation_um=2"])
    case = Case("bem-fft", scene, {"cells_per_diameter": 8})
    with Engine("serial", quiet=True) as engine:
        first = engine.run([case], tmp_path)[0].unwrap()
        again = engine.run([case], tmp_path)[0]
    assert first.floor_force_N > 0.1 * first.total_force_N and first.regime == "mixed"
    assert again.cached and again.result.total_force_N == first.total_force_N
