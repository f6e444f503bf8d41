"""The CLI fuzz grown by what a damaged pillar compliance cache did: each case one exit status
of the failure policy, at most one line on stderr, never a traceback, a hang or a wrong
answer.

The pillar compliance here is a synthetic operator of the right shapes (identity mode
matrices: no finite-element solve), handed to the cache by a stand-in for the build, so that
a rebuild takes milliseconds and each CLI run about as long as a dense BEM solve at P = 5.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from test_cli_fuzz_wide import check
from test_compliance_store import rewrite_arrays

SCENE = ["--scene", "single-pillar", "--set", "pillars.E_Pa=1.6e7"]
SOLVE = ["solve", *SCENE, "--elements-per-diameter", "5", "--pillars", "elastic", "--json"]


def synthetic_build(kind, modes, mesh_size, progress=None):
    """A stand-in for the compliance build: identity mode matrices on 9 top points."""
    from fem_reference import ModalCompliance

    r = np.linspace(0.0, 1.0, 9)
    c = np.tile(np.eye(9) * 0.05, (modes + 1, 1, 1))
    return ModalCompliance(kind, modes, mesh_size, r, c, c / 2, {}, np.tile(r * r, (2, 1)))


@pytest.fixture
def store(tmp_path, monkeypatch):
    """A fresh compliance cache with the synthetic build; returns (cache root, built kinds)."""
    from fem_reference import _pillar_compliance

    built = []

    def build(kind, modes, mesh_size, progress=None):
        built.append(kind)
        return synthetic_build(kind, modes, mesh_size, progress)

    monkeypatch.setattr(_pillar_compliance, "compute_modal_compliance", build)
    root = tmp_path / "cache"
    monkeypatch.setenv("PILLAR_XVAL_CACHE", str(root))
    return root, built


def _the_file(root: Path) -> Path:
    (path,) = [p for p in (root / "pillar-compliance").glob("*.npz")]
    return path


def _warnings(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ": warning: CacheWarning: " in ln]


DAMAGE = {
    "pillar scaled by 10": lambda p: rewrite_arrays(p, pillar=lambda a: 10 * a),
    "r_top doubled": lambda p: rewrite_arrays(p, r_top=lambda a: 2 * a),
    "halfspace zeroed": lambda p: rewrite_arrays(p, halfspace=lambda a: 0 * a),
    "wrong shapes": lambda p: rewrite_arrays(p, pillar=lambda a: a[:3]),
    "NaN": lambda p: rewrite_arrays(p, pillar=lambda a: np.where(a == a.max(), np.nan, a)),
    "truncated zip": lambda p: p.write_bytes(p.read_bytes()[:100]),
    "empty file": lambda p: p.write_bytes(b""),
}


@pytest.mark.parametrize("damage", DAMAGE)
def test_solve_with_a_damaged_compliance_file(cli, store, damage):
    """Once: exit 0 with a wrong F_T (scaled arrays, a doubled r_top, a zeroed halfspace), or
    exit 4 naming no file (a truncated zip, an empty file, wrong shapes, NaN), on every run
    until the file was deleted."""
    root, built = store
    code, out, err = cli(*SOLVE)
    assert code == 0, err
    truth = json.loads(out)["total_force_N"]
    path = _the_file(root)
    DAMAGE[damage](path)
    code, out, err = cli(*SOLVE)
    check(code, out, err)
    assert code == 0 and json.loads(out)["total_force_N"] == truth
    (line,) = _warnings(err)
    assert str(path) in line and "rebuilding" in line
    assert len(built) == 2
    code, out, err = cli(*SOLVE)   # repaired for good
    assert code == 0 and not _warnings(err) and len(built) == 2


def test_solve_with_another_kinds_file_copied_or_linked_over(cli, store):
    """Another kind's valid file copied over gave F_T +60 % with exit 0; a link to it too."""
    root, built = store
    code, out, err = cli(*SOLVE)
    assert code == 0, err
    truth = json.loads(out)["total_force_N"]
    path = _the_file(root)
    shutil.move(path, root / "mine.npz")
    code, _, err = cli("solve", "--scene", "single-pillar", "--set", "pillars.E_Pa=1.6e8",
                       "--elements-per-diameter", "5", "--pillars", "elastic", "--json")
    assert code == 0, err
    foreign = _the_file(root)
    shutil.move(foreign, root / "foreign.npz")
    for put in (shutil.copyfile, os.symlink):
        put(root / "foreign.npz", path)
        code, out, err = cli(*SOLVE)
        assert code == 0 and json.loads(out)["total_force_N"] == truth, err
        (line,) = _warnings(err)
        assert str(path) in line and "another operator" in line
        path.unlink()


def test_auto_with_a_damaged_compliance_file(cli, store):
    """`solve --model auto` once picked the elastic BEM because a (damaged) file existed,
    then crashed with exit 4: a damaged file is now no cached compliance, its rebuild is
    charged in the plan, and the elastic BEM, when chosen, rebuilds it."""
    from fem_reference import DEFAULT_MODES, PillarKind, modal_compliance
    from pillar_xval.scenes import load_scene

    root, built = store
    scene = [*SCENE, "--tolerance", "0.02"]
    modal_compliance(PillarKind.of_scene(load_scene(SCENE[1], [SCENE[3]])), DEFAULT_MODES, 1.0)

    def setups():
        code, out, err = cli("plan", *scene, "--json")
        assert code == 0, err
        return {c["setup_s"] for c in json.loads(out)["candidates"] if "elastic" in c["label"]}

    assert setups() == {0.0}
    code, out, err = cli("solve", *scene, "--model", "auto", "--json")
    assert code == 0 and "elastic" in json.dumps(json.loads(out)["diagnostics"]["plan"]["choice"])
    rewrite_arrays(_the_file(root), pillar=lambda a: a[:3])
    assert min(setups()) > 0
    code, out, err = cli("solve", *scene, "--model", "auto", "--json")
    check(code, out, err)
    assert code == 0


def test_solve_with_an_unusable_cache(cli, store):
    """A cache that cannot be written once threw the build away and exited 3."""
    root, built = store
    root.mkdir(parents=True)
    (root / "pillar-compliance").write_text("a file where the cache folder should be")
    code, out, err = cli(*SOLVE)
    check(code, out, err)
    assert code == 0 and json.loads(out)["total_force_N"] > 0
    (line,) = _warnings(err)
    assert "cannot be used" in line and len(built) == 1


FIFO_RUN = """
import sys
sys.path.insert(0, {tests!r})
from fem_reference import _pillar_compliance
from test_cli_fuzz_cache import synthetic_build
_pillar_compliance.compute_modal_compliance = synthetic_build
from validation.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_solve_with_a_fifo_at_the_cache_path(tmp_path):
    """A FIFO at the cache path once blocked the command forever."""
    env = {**os.environ, "PILLAR_XVAL_CACHE": str(tmp_path)}
    script = FIFO_RUN.format(tests=str(Path(__file__).parent))
    run = [sys.executable, "-c", script, *SOLVE]
    first = subprocess.run(run, capture_output=True, text=True, env=env, timeout=120)
    assert first.returncode == 0, first.stderr
    path = _the_file(tmp_path)
    path.unlink()
    os.mkfifo(path)
    out = subprocess.run(run, capture_output=True, text=True, env=env, timeout=60)
    check(out.returncode, out.stdout, out.stderr)
    assert out.returncode == 0
    assert json.loads(out.stdout)["total_force_N"] == \
        json.loads(first.stdout)["total_force_N"]
    (line,) = _warnings(out.stderr)
    assert "not a regular file (a FIFO)" in line and path.is_file()


def test_a_sweep_case_is_recomputed_after_its_operator_is_replaced(cli, store, tmp_path):
    """Study cases computed with a bad operator once stayed cached after the repair."""
    root, built = store
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "single-pillar"\nset = ["pillars.E_Pa=1.6e7"]\n[grid]\n'
                    '"load.indentation_um" = [0.2]\n[[models]]\nname = "bem"\n'
                    'elements_per_diameter = 5\npillars = "elastic"\n')
    run = ("sweep", spec, "--out", tmp_path / "o", "--executor", "serial", "--json")
    code, out, err = cli(*run)
    assert code == 0, err
    first = json.loads(out)["rows"][0]["total_force_N"]
    # Replaced by another valid operator (a bad one that verifies, or a repair).
    from fem_reference import _pillar_compliance

    path = _the_file(root)
    path.unlink()
    original = synthetic_build

    def stiffer(kind, modes, mesh_size, progress=None):
        op = original(kind, modes, mesh_size)
        op.pillar = op.pillar / 4
        return op

    _pillar_compliance.compute_modal_compliance = stiffer
    code, out, err = cli(*run)
    check(code, out, err)
    assert "recomputing" in err and "the cache now holds" in err
    assert json.loads(out)["rows"][0]["total_force_N"] != pytest.approx(first, rel=1e-6)
