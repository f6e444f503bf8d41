"""The code passes its linter and its type check, as configured in pyproject.toml (ruff's
rules; mypy on the solver packages' public modules), and every package ships py.typed."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pillar_xval", "bem_solver", "fem_reference", "meshes", "validation")


def _tool(module: str, *args: str) -> subprocess.CompletedProcess:
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not installed (pip install -e '.[lint]')")
    return subprocess.run([sys.executable, "-m", module, *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


def test_ruff_is_clean():
    out = _tool("ruff", "check", "--no-cache", "--output-format", "concise", ".")
    assert out.returncode == 0, out.stdout[-6000:] + out.stderr[-2000:]


def test_public_api_type_checks():
    out = _tool("mypy", "--no-incremental")
    assert out.returncode == 0, out.stdout[-6000:] + out.stderr[-2000:]


def test_every_package_ships_py_typed():
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    for package in PACKAGES:
        assert (ROOT / package / "py.typed").is_file(), package
        assert "py.typed" in config["package-data"].get(package, []), package
