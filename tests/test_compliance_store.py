"""The pillar compliance cache as a trusted store (fem_reference._compliance_store).

One operator is built for real, once per module (coarse: mesh_size 4, one mode, seconds);
every rebuild below is that operator handed back by a stand-in for the build
(``fem_reference._pillar_compliance.compute_modal_compliance``), counted, so that each test
takes milliseconds and says how many builds a scenario cost.  The files are damaged as a user
or a crash would: every kind of damage must give one warning naming the file, one rebuild
and the true operator, never a wrong answer, an exception or a hang.
"""

from __future__ import annotations

import copy
import os
import shutil
import subprocess
import sys
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest

import fem_reference
from fem_reference import PillarKind, _pillar_compliance

KIND = PillarKind(0.5, 1.0, 0.5, 0.5)
OTHER = PillarKind(0.5, 10.0, 0.5, 0.5)
COARSE = {"modes": 1, "mesh_size": 4.0}
# A read of a FIFO once blocked forever; a correct store answers in milliseconds.
HANG_S = 30.0


@pytest.fixture(scope="module")
def pristine(tmp_path_factory):
    """The true operator of KIND (built once), the bytes of its cache file and its name."""
    folder = tmp_path_factory.mktemp("pristine")
    mp_ = pytest.MonkeyPatch()
    mp_.setenv("PILLAR_XVAL_CACHE", str(folder))
    op = fem_reference.modal_compliance(KIND, **COARSE)
    (path,) = _files(folder)
    data = path.read_bytes()
    mp_.undo()
    return op, data, path.name


def _files(cache) -> list[Path]:
    folder = Path(cache) / "pillar-compliance"
    return sorted(p for p in folder.iterdir() if p.suffix == ".npz"
                  and not p.name.startswith(".")) if folder.is_dir() else []


def _everything(cache) -> list[str]:
    """Every name under the cache (temporary files included), lock files left out."""
    return sorted(str(p.relative_to(cache)) for p in Path(cache).rglob("*")
                  if ".locks" not in p.parts)


@pytest.fixture
def builds(monkeypatch, pristine):
    """Stand-in for the build: KIND's true operator (OTHER's: the same arrays times 1.6, a
    different operator); returns the list of kinds built."""
    op = pristine[0]
    built = []

    def build(kind, modes, mesh_size, progress=None):
        built.append(kind)
        out = copy.deepcopy(op)
        out.kind = kind
        out.diagnostics = {k: v for k, v in out.diagnostics.items()
                           if k not in ("cached", "operator")}
        if kind != KIND:
            out.pillar, out.halfspace = 1.6 * out.pillar, 1.6 * out.halfspace
        return out

    monkeypatch.setattr(_pillar_compliance, "compute_modal_compliance", build)
    return built


@pytest.fixture
def cache(tmp_path, monkeypatch, pristine):
    """A cache holding KIND's true operator; returns (cache root, its file)."""
    monkeypatch.setenv("PILLAR_XVAL_CACHE", str(tmp_path))
    folder = tmp_path / "pillar-compliance"
    folder.mkdir()
    path = folder / pristine[2]
    path.write_bytes(pristine[1])
    return tmp_path, path


def rewrite_arrays(path: Path, **change):
    """Rewrite the npz file ``path`` with ``change[name](array)`` for the named arrays (a
    damaged file, as an editor would leave it: every array there, no new hash)."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    for k, fn in change.items():
        arrays[k] = fn(arrays[k])
    path.unlink()
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _other_kinds_file(cache_root: Path) -> Path:
    """A valid file of OTHER (its own cache), for copying or linking over KIND's."""
    root = cache_root / "other"
    old = os.environ["PILLAR_XVAL_CACHE"]
    os.environ["PILLAR_XVAL_CACHE"] = str(root)
    try:
        fem_reference.modal_compliance(OTHER, **COARSE)
    finally:
        os.environ["PILLAR_XVAL_CACHE"] = old
    return _files(root)[0]


def _nth(value):
    def put(a):
        a = a.copy()
        a.flat[5] = value
        return a
    return put


DAMAGE = {
    "pillar scaled by 10": lambda p, root: rewrite_arrays(p, pillar=lambda a: 10 * a),
    "r_top doubled": lambda p, root: rewrite_arrays(p, r_top=lambda a: 2 * a),
    "halfspace zeroed": lambda p, root: rewrite_arrays(p, halfspace=lambda a: 0 * a),
    "wrong shapes": lambda p, root: rewrite_arrays(p, pillar=lambda a: a[:1]),
    "NaN": lambda p, root: rewrite_arrays(p, pillar=_nth(np.nan)),
    "inf": lambda p, root: rewrite_arrays(p, halfspace=_nth(np.inf)),
    "truncated zip": lambda p, root: p.write_bytes(p.read_bytes()[:len(p.read_bytes()) // 2]),
    "empty file": lambda p, root: p.write_bytes(b""),
    "another kind's file copied over it": lambda p, root: shutil.copyfile(
        _other_kinds_file(root), p),
    "a symlink to another kind's file": lambda p, root: (p.unlink(), p.symlink_to(
        _other_kinds_file(root))),
    "a FIFO": lambda p, root: (p.unlink(), os.mkfifo(p)),
}


def _call(kind=KIND, **kwargs):
    """modal_compliance in a thread, so that a read that blocks fails the test instead of
    hanging it; returns (operator, warnings)."""
    out = {}

    def run():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                out["op"] = fem_reference.modal_compliance(kind, **{**COARSE, **kwargs})
            except BaseException as exc:  # handed to the test below
                out["error"] = exc
        out["warnings"] = [str(w.message) for w in caught
                           if issubclass(w.category, UserWarning)]

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(HANG_S)
    assert not thread.is_alive(), f"modal_compliance blocked for {HANG_S} s"
    if "error" in out:
        raise out["error"]
    return out["op"], out["warnings"]


def test_a_valid_file_is_read_and_verified(cache, builds, pristine):
    op, said = _call()
    assert builds == [] and said == [] and op.diagnostics["cached"]
    np.testing.assert_array_equal(op.pillar, pristine[0].pillar)
    assert op.diagnostics["operator"] == pristine[0].diagnostics["operator"]


@pytest.mark.parametrize("damage", DAMAGE)
def test_a_damaged_or_foreign_file_is_rebuilt_with_one_line_naming_it(cache, builds, pristine,
                                                                      damage):
    root, path = cache
    DAMAGE[damage](path, root)
    builds.clear()   # the other kind's file, where the damage needs one
    op, said = _call()
    # The true operator, rebuilt once, the file named in one warning ...
    assert builds == [KIND]
    for name in ("r_top", "pillar", "halfspace", "base_moments"):
        np.testing.assert_array_equal(getattr(op, name), getattr(pristine[0], name))
    assert len(said) == 1 and str(path) in said[0] and "rebuilding" in said[0], said
    assert "\n" not in said[0]
    # ... and replaced by a valid file (a link replaced, not its target): read next time.
    assert path.is_file() and not path.is_symlink()
    again, said = _call()
    assert builds == [KIND] and said == [] and again.diagnostics["cached"]


def test_a_folder_at_the_file_path_is_left_alone_and_the_operator_computed(cache, builds,
                                                                           pristine):
    _, path = cache
    path.unlink()
    (path / "a user's file").mkdir(parents=True)
    op, said = _call()
    np.testing.assert_array_equal(op.pillar, pristine[0].pillar)
    assert builds == [KIND] and len(said) == 2 and all(str(path) in s for s in said), said
    assert "not a regular file (a folder)" in said[0] and "cannot store" in said[1]
    assert (path / "a user's file").is_dir()


def test_an_unusable_cache_folder_still_gives_the_operator(tmp_path, monkeypatch, builds,
                                                          pristine):
    """A file where the cache folder should be: the operator is computed and returned, with
    one warning (a read-only cache once threw away the build and exited 3)."""
    (tmp_path / "pillar-compliance").write_text("not a folder")
    monkeypatch.setenv("PILLAR_XVAL_CACHE", str(tmp_path))
    op, said = _call()
    np.testing.assert_array_equal(op.pillar, pristine[0].pillar)
    assert builds == [KIND] and len(said) == 1 and "cannot be used" in said[0]


@pytest.mark.skipif(os.geteuid() == 0, reason="permissions do not bind root")
def test_a_read_only_cache_folder_still_gives_the_operator(tmp_path, monkeypatch, builds,
                                                          pristine):
    folder = tmp_path / "pillar-compliance"
    folder.mkdir()
    folder.chmod(0o555)
    monkeypatch.setenv("PILLAR_XVAL_CACHE", str(tmp_path))
    try:
        op, said = _call()
    finally:
        folder.chmod(0o755)
    np.testing.assert_array_equal(op.pillar, pristine[0].pillar)
    assert len(said) == 1 and not list(folder.iterdir())


# A process that stands in a synthetic operator for the build (no solver: a forked or fresh
# process then needs no PARDISO), logs each build and calls modal_compliance.
PROCESS = """
import os, sys, time, warnings
import numpy as np
import fem_reference
from fem_reference import PillarKind, _pillar_compliance
from fem_reference._pillar_compliance import ModalCompliance

def build(kind, modes, mesh_size, progress=None):
    with open(os.environ["BUILD_LOG"], "a") as fh:
        fh.write(f"{os.getpid()}\\n")
    time.sleep(float(os.environ.get("BUILD_S", "0")))
    n = 41
    r = np.linspace(0.0, 1.0, n)
    c = np.tile(np.eye(n), (modes + 1, 1, 1))
    return ModalCompliance(kind, modes, mesh_size, r, c, 0.5 * c, {}, np.tile(r * r, (2, 1)))

_pillar_compliance.compute_modal_compliance = build
warnings.simplefilter("always")
%s
op = fem_reference.modal_compliance(PillarKind(0.5, 1.0, 0.5, 0.5), 1, mesh_size=4.0)
print("returned", op.pillar.shape, op.diagnostics["cached"])
"""
# The operator's file is ~30 kB: a 16 kB file size limit fails its write half-way, as a full
# disk does (Python ignores SIGXFSZ, so the write raises EFBIG).
FILE_SIZE_LIMIT = """
import resource
resource.setrlimit(resource.RLIMIT_FSIZE, (16384, 16384))
"""
# Both processes wait for each other, then ask for the same kind.
TOGETHER = """
from pathlib import Path
ready = Path(os.environ["BUILD_LOG"]).with_name(f"ready-{os.getpid()}")
ready.touch()
deadline = time.monotonic() + 60
while len(list(ready.parent.glob("ready-*"))) < 2 and time.monotonic() < deadline:
    time.sleep(0.01)
"""


def _process(tmp_path, extra: str, **env):
    return subprocess.Popen([sys.executable, "-c", PROCESS % extra], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PILLAR_XVAL_CACHE": str(tmp_path / "cache"),
                                 "BUILD_LOG": str(tmp_path / "builds.log"), **env})


def test_a_failed_write_leaves_nothing_behind_and_returns_the_operator(tmp_path):
    """A write that fails half-way once left KEY.PID.tmp.npz behind (on a full disk, a
    partial file that kept it full) and threw the operator away."""
    out, err = _process(tmp_path, FILE_SIZE_LIMIT).communicate(timeout=120)
    assert "returned (2, 41, 41) False" in out, err
    assert "cannot store" in err and "File too large" in err
    assert _everything(tmp_path / "cache") == ["pillar-compliance"]


def test_two_processes_build_one_kind_once(tmp_path):
    """Two commands (or two pool workers of one sweep) once built the same kind at once."""
    procs = [_process(tmp_path, TOGETHER, BUILD_S="1.5") for _ in range(2)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], outs
    assert len((tmp_path / "builds.log").read_text().split()) == 1
    assert sorted(o.split()[-1] for o, _ in outs) == ["False", "True"]


def test_the_cache_key_and_the_file_name_stay_inside_the_cache(cache, builds):
    from fem_reference._compliance_store import stored_digest

    root, path = cache
    assert stored_digest(path.stem) is not None
    for key in ("../" + path.stem, path.stem + "/..", "", None, 7, path.stem.upper()):
        assert stored_digest(key) is None


def test_a_case_computed_with_a_replaced_operator_is_recomputed(cache, monkeypatch, pristine,
                                                                tmp_path):
    """The damage once outlived the repair: a study case computed with a bad operator stayed
    cached as valid after the good file was back, since its key did not cover the operator.
    A case's record now holds the content hash of each operator it used, and is reused only
    while the cache holds that operator."""
    from pillar_xval.scenes import load_scene
    from validation.engine import Case, Engine

    scale = {"factor": 10.0}
    full = fem_reference.modal_compliance

    def build(kind, modes, mesh_size, progress=None):
        out = copy.deepcopy(pristine[0])
        out.diagnostics = {}
        out.pillar, out.halfspace = scale["factor"] * out.pillar, scale["factor"] * out.halfspace
        return out

    monkeypatch.setattr(_pillar_compliance, "compute_modal_compliance", build)
    monkeypatch.setattr(fem_reference, "modal_compliance",
                        lambda kind, modes, mesh_size, progress=None: full(kind, **COARSE))
    root, path = cache
    path.unlink()
    case = Case("bem", load_scene("single-pillar"), {"elements_per_diameter": 5,
                                                     "pillars": "elastic"})
    folder = tmp_path / "study"
    with Engine("serial", quiet=True) as engine:
        bad = engine.run_one(case, folder)
    assert not bad.cached and _files(root)
    # The repair: the bad file removed, the true operator built in its place.
    for f in _files(root):
        f.unlink()
    scale["factor"] = 1.0
    fem_reference.modal_compliance(KIND, **COARSE)
    with Engine("serial", quiet=True) as engine:
        good = engine.run_one(case, folder)
        again = engine.run_one(case, folder)
    assert not good.cached and again.cached
    assert good.result.total_force_N != pytest.approx(bad.result.total_force_N, rel=1e-3)
    used = good.result.diagnostics["operators"]
    assert [u["sha256"] for u in used] == [fem_reference.modal_compliance(
        KIND, **COARSE).diagnostics["operator"]["sha256"]]
