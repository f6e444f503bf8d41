"""Threads from the CPUs a process may use (pillar_xval.threads): the count (affinity mask,
cgroup quota, the override), its use by the solvers, and the engine's share per worker."""

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import fakes
from pillar_xval import threads
from pillar_xval.scenes import InputError, load_scene
from validation.engine import Case, Engine
from validation.engine._executors import default_workers, threads_per_worker

ROOT = Path(__file__).resolve().parents[1]
# A solve on one thread may show a little more than one CPU-second per second: the
# interpreter's own helper threads and the kernel's accounting (the bound, 1.1).
ONE_THREAD_CPU_PER_WALL = 1.1


def _cgroup(tmp_path, membership: str, files: dict) -> tuple[Path, Path]:
    """A fake /sys/fs/cgroup tree and /proc/self/cgroup file."""
    root = tmp_path / "cgroup"
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    proc = tmp_path / "membership"
    proc.write_text(membership)
    return root, proc


@pytest.mark.parametrize("membership, files, cpus", [
    ("0::/job\n", {"job/cpu.max": "150000 100000\n"}, 1.5),
    ("0::/job\n", {"job/cpu.max": "max 100000\n"}, None),
    # a quota set on the parent binds the child too
    ("0::/a/b\n", {"a/cpu.max": "200000 100000", "a/b/cpu.max": "max 100000"}, 2.0),
    ("0::/a/b\n", {"a/cpu.max": "400000 100000", "a/b/cpu.max": "300000 100000"}, 3.0),
    # cgroup v1: -1 is no quota; cpu,cpuacct mounts as its own folder
    ("4:cpu,cpuacct:/x\n", {"cpu,cpuacct/x/cpu.cfs_quota_us": "-1",
                           "cpu,cpuacct/x/cpu.cfs_period_us": "100000"}, None),
    ("4:cpu,cpuacct:/x\n", {"cpu,cpuacct/x/cpu.cfs_quota_us": "50000",
                           "cpu,cpuacct/x/cpu.cfs_period_us": "100000"}, 0.5),
    ("1:cpu:/\n", {"cpu/cpu.cfs_quota_us": "250000", "cpu/cpu.cfs_period_us": "100000"}, 2.5),
    ("garbage\n", {"cpu.max": "100000 100000"}, None),
    ("0::/\n", {"cpu.max": "not a number"}, None),
])
def test_cgroup_quota_is_read_from_v2_and_v1(tmp_path, membership, files, cpus):
    root, proc = _cgroup(tmp_path, membership, files)
    assert threads.cgroup_cpus(root, proc) == cpus


@pytest.mark.parametrize("affinity, quota, expected", [
    (8, None, 8), (8, 2.5, 2), (8, 0.5, 1), (2, 16.0, 2), (1, None, 1)])
def test_cpu_count_is_the_affinity_limited_by_the_quota(monkeypatch, affinity, quota,
                                                        expected):
    monkeypatch.setattr(threads, "_affinity", lambda: affinity)
    monkeypatch.setattr(threads, "cgroup_cpus", lambda: quota)
    assert threads.cpu_count() == expected


def test_the_override_and_its_refusals(monkeypatch):
    monkeypatch.delenv(threads.THREADS_ENV, raising=False)
    assert threads.thread_count() == threads.cpu_count()
    monkeypatch.setenv(threads.THREADS_ENV, "3")
    assert threads.thread_count() == 3
    with threads.threads_override(5):
        assert threads.thread_count() == 5
    assert os.environ[threads.THREADS_ENV] == "3"
    for bad in ("0", "-1", "2.5", "x", str(threads.MAX_THREADS + 1)):
        monkeypatch.setenv(threads.THREADS_ENV, bad)
        with pytest.raises(InputError, match=rf"{threads.THREADS_ENV} = '{bad}'.*\[1, "):
            threads.thread_count()


def test_taskset_counts_one_cpu():
    """Under ``taskset -c 0`` the toolkit counts one CPU and plans one thread."""
    if shutil.which("taskset") is None or not hasattr(os, "sched_getaffinity"):
        pytest.skip("taskset is not available here")
    env = {k: v for k, v in os.environ.items() if k != threads.THREADS_ENV}
    code = ("from pillar_xval.threads import cpu_count, thread_count; "
            "from validation.engine import default_workers; "
            "print(cpu_count(), thread_count(), default_workers())")
    out = subprocess.run(["taskset", "-c", "0", sys.executable, "-c", code], env=env,
                         capture_output=True, text=True, check=True, cwd=ROOT).stdout
    assert out.split() == ["1", "1", "1"]


def test_one_thread_holds_a_million_cell_fft_solve_to_one_cpu():
    """With one thread allowed, a bem-fft solve on a 1005 x 1005 grid (1.0e6 cells, 6.8e5
    candidates) takes at most 1.1 CPU-seconds per second of wall time (CPU time of the
    process, every thread, over wall time around the solve; a few CG iterations).  On a
    loaded machine the ratio can only fall."""
    code = textwrap.dedent("""
        import json, time
        from pillar_xval.scenes import load_scene
        from validation.registry import run_model
        scene = load_scene("paper-fig3-dense")
        t, c = time.perf_counter(), time.process_time()
        r = run_model("bem-fft", scene, cells_per_diameter=58, max_iterations=3)
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        d = r.diagnostics
        print(json.dumps({"wall": wall, "cpu": cpu, "grid": d["grid_shape"]}))
    """)
    env = {**os.environ, threads.THREADS_ENV: "1"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout
    run = json.loads(out.splitlines()[-1])
    assert run["grid"][0] * run["grid"][1] >= 1_000_000
    assert run["cpu"] <= ONE_THREAD_CPU_PER_WALL * run["wall"], run


def test_the_solvers_read_the_count(monkeypatch):
    from bem_solver._xp import NumpyDevice, select_backend

    monkeypatch.setenv(threads.THREADS_ENV, "3")
    assert NumpyDevice().workers == 3 and select_backend("cpu").workers == 3
    assert NumpyDevice(workers=1).workers == 1
    with threads.limited(1):
        from threadpoolctl import threadpool_info

        assert all(lib["num_threads"] == 1 for lib in threadpool_info())


@pytest.mark.parametrize("count", [1, 2, 3, 5, 16, 64])
def test_the_engine_never_oversubscribes(monkeypatch, count):
    monkeypatch.setenv(threads.THREADS_ENV, str(count))
    assert default_workers() * threads_per_worker(default_workers()) <= count
    for workers in range(1, count + 1):
        share = threads_per_worker(workers)
        assert workers * share <= count and share >= 1
        assert share == count // workers  # all of them used where they divide evenly


def report_threads(scene, mesh_size=1.0):
    """A fake model: the threads it was given, as seen inside the worker."""
    from threadpoolctl import threadpool_info

    result = fakes._result("fem-axisym", scene, 1.0, {"mesh_size": mesh_size})
    result.diagnostics["threads"] = threads.thread_count()
    result.diagnostics["blas"] = max(lib["num_threads"] for lib in threadpool_info())
    result.diagnostics["pid"] = os.getpid()
    return result


@pytest.mark.parametrize("workers, count", [(None, 2), (2, 4), (3, 4)])
def test_pool_workers_share_the_threads(monkeypatch, tmp_path, workers, count):
    """Each pool worker solves on its share (BLAS included): workers x threads <= count."""
    monkeypatch.setenv(threads.THREADS_ENV, str(count))
    fakes.register(monkeypatch, "fem-axisym", "test_threads:report_threads", ("mesh_size",))
    scene = load_scene("single-pillar")
    cases = [Case("fem-axisym", scene, {"mesh_size": 1.0 + k}) for k in range(6)]
    with Engine("pool", workers=workers, quiet=True) as engine:
        outcomes = engine.run(cases, tmp_path / "cases")
    n = workers or count
    got = [o.unwrap().diagnostics for o in outcomes]
    assert len({d["pid"] for d in got}) <= n
    assert all(d["threads"] == count // n and d["blas"] <= count // n for d in got), got


def test_cli_threads_option_reaches_the_solve(monkeypatch, cli):
    monkeypatch.delenv(threads.THREADS_ENV, raising=False)
    fakes.register(monkeypatch, "fem-axisym", "test_threads:report_threads", ("mesh_size",))
    code, out, err = cli("solve", "--scene", "single-pillar", "--model", "fem-axisym",
                         "--threads", "1", "--json")
    assert code == 0, err
    assert json.loads(out)["diagnostics"]["threads"] == 1
    assert threads.THREADS_ENV not in os.environ  # restored after the command
    code, _, err = cli("solve", "--scene", "single-pillar", "--threads", "0")
    assert code == 2 and "--threads" in err and "[1, " in err


@pytest.mark.parametrize("scene_name", ["hertz", "single-pillar"])
def test_gmsh_meshes_the_same_wedge_on_one_and_two_threads(monkeypatch, scene_name):
    """gmsh's threads change no mesh (curves and surfaces stay on one thread: on two they
    came out different on every run, on these scenes too), so fem-3d's answers do not
    depend on them."""
    from fem_reference.solid3d.driver import BLOCK_FACTOR, _setup
    from meshes import build_wedge_mesh

    geometry = _setup(load_scene(scene_name), 4.0, np.pi / 6, BLOCK_FACTOR, 1.0,
                      {})["geometry"]
    meshes = []
    for count in ("1", "2", "2"):
        monkeypatch.setenv(threads.THREADS_ENV, count)
        meshes.append(build_wedge_mesh(geometry))
    for other in meshes[1:]:
        assert other.points.shape == meshes[0].points.shape
        assert np.array_equal(other.points, meshes[0].points)
        assert np.array_equal(other.tets, meshes[0].tets)
