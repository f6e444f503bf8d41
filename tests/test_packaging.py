"""The installed package: the wheel's top-level import names, and the wheel installed (not
editable) beside trio, whose dependency ``outcome`` once shadowed a package of ours and broke
every command.

The fresh environment borrows the project environment's dependencies through a ``.pth`` line
(its site-packages added as a plain path: the editable install's own ``.pth`` there is not
processed), so the test needs no network and takes seconds.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# The user's four folders and the project's one package: nothing else is installed.
TOP_LEVEL = {"bem_solver", "fem_reference", "meshes", "validation", "pillar_xval"}
SOURCES = ("pyproject.toml", "README.md", *sorted(TOP_LEVEL))


def _run(cmd, cwd, timeout=120):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    out = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=timeout)
    assert out.returncode == 0, f"{cmd}: exit {out.returncode}\n{out.stdout}\n{out.stderr}"
    return out.stdout


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The project's wheel, built from a copy of its sources (no build folder in the tree)."""
    src = tmp_path_factory.mktemp("src")
    for name in SOURCES:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(path, src / name)
    dist = tmp_path_factory.mktemp("dist")
    _run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
          "--wheel-dir", dist, src], cwd=src)
    wheels = list(dist.glob("pillar_xval-*.whl"))
    assert len(wheels) == 1, wheels
    return wheels[0]


def test_the_wheel_installs_five_top_level_names(wheel):
    with zipfile.ZipFile(wheel) as archive:
        tops = {name.split("/", 1)[0] for name in archive.namelist()}
    tops = {t for t in tops if not t.endswith((".dist-info", ".data"))}
    assert tops == TOP_LEVEL
    # The scene presets and the planner's data travel with the wheel.
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
    assert "pillar_xval/scenes/presets/hertz.toml" in names
    assert any(n.startswith("validation/planner/data/") and n.endswith(".json") for n in names)


def test_the_wheel_works_beside_trio(wheel, tmp_path):
    env = tmp_path / "env"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", env], check=True,
                   timeout=60)
    python = env / "bin" / "python"
    purelib = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                        cwd=tmp_path).strip())
    (purelib / "project_deps.pth").write_text(sysconfig.get_path("purelib") + "\n")
    _run([sys.executable, "-m", "pip", "--python", python, "install", "--quiet", "--no-deps",
          "--no-index", wheel], cwd=tmp_path)
    work = tmp_path / "work"
    work.mkdir()

    where = _run([python, "-c", "import trio, outcome, validation, pillar_xval; "
                  "print(outcome.__file__); print(validation.__file__)"], cwd=work).split()
    assert "pillar_xval" not in where[0]  # trio's outcome, not ours
    assert where[1].startswith(str(purelib)), where  # the wheel, not the repository

    out = _run([env / "bin" / "pillar-xval", "solve", "--scene", "hertz", "--out",
                work / "hertz"], cwd=work)
    assert "converged" in out and (work / "hertz" / "result.json").is_file()

    (work / "test_user.py").write_text(
        "def test_hertz(xval):\n"
        "    scene = xval.scene('hertz')\n"
        "    result = xval.run('hertz', scene)\n"
        "    assert result.converged and result.total_force_N > 0\n")
    out = _run([python, "-m", "pytest", "-q", "test_user.py"], cwd=work)
    assert "1 passed" in out
