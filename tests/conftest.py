"""Shared fixtures: the fake models (tests/fakes.py) and the CLI run in-process."""

import os
import sys
import types

import pytest

import fakes as fake_models
from pillar_xval import threads
from validation.cli import main

# Plans with the cost fits' own seconds (no machine calibration): the same plans on every
# machine and under any load, in this process and the commands it starts;
# tests/test_planner_machine.py calibrates on purpose.
os.environ.setdefault("PILLAR_XVAL_MACHINE", "reference")

# Under pytest-xdist the workers share the CPUs this process may use: each solve takes its
# share of them (at least one thread), so that n workers never run n times the CPUs' threads.
if "PYTEST_XDIST_WORKER_COUNT" in os.environ:
    _share = threads.cpu_count() // int(os.environ["PYTEST_XDIST_WORKER_COUNT"])
    os.environ.setdefault(threads.THREADS_ENV, str(max(1, _share)))


@pytest.hookimpl(optionalhook=True)  # a hook of pytest-xdist's, absent under -p no:xdist
def pytest_xdist_auto_num_workers(config):
    """``-n auto``: one worker per CPU this process may use (its affinity and cgroup quota),
    not one per CPU the machine has."""
    return threads.cpu_count()


@pytest.fixture
def fakes(monkeypatch):
    """Register the fake 'bem' and 'fem-axisym' in the model registry."""
    mod = types.ModuleType("xval_fakes")
    mod.fake_fem, mod.fake_bem = fake_models.fake_fem, fake_models.fake_bem
    monkeypatch.setitem(sys.modules, "xval_fakes", mod)
    fake_models.register(monkeypatch, "fem-axisym", "xval_fakes:fake_fem", ("mesh_size",))
    fake_models.register(monkeypatch, "bem", "xval_fakes:fake_bem",
                         ("elements_per_diameter", "cells", "contact"))
    fake_models.CALLS.clear()
    return fake_models.CALLS


@pytest.fixture
def cli(capsys):
    """Run ``pillar-xval ARGV`` in-process: returns (exit status, stdout, stderr)."""
    def run(*argv):
        code = main([str(a) for a in argv])
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return run


@pytest.fixture(scope="module")
def compliance_cache(tmp_path_factory):
    """A fresh pillar-compliance cache (PILLAR_XVAL_CACHE) for one test module: its operators
    are built once there, never read from the user's cache."""
    mp = pytest.MonkeyPatch()
    mp.setenv("PILLAR_XVAL_CACHE", str(tmp_path_factory.mktemp("compliance")))
    yield
    mp.undo()
