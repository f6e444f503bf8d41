"""The memory pre-check obeys the process's own limit, not only the machine's free memory."""

from __future__ import annotations

import resource
import subprocess
import sys

import pytest

from pillar_xval.outcome.memory import MEMORY_SHARE, memory_limit, memory_short

LIMIT = 2_000_000 * 1024  # ulimit -v 2000000 (KiB), as a user would set it


def _limited():
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          preexec_fn=_limited, timeout=120)


def test_the_address_space_limit_binds_under_ulimit():
    out = _run("from pillar_xval.outcome.memory import memory_limit; b, w = memory_limit(); "
               "print(b); print(w)")
    assert out.returncode == 0, out.stderr
    free, what = out.stdout.splitlines()
    assert "ulimit -v" in what
    assert 0 < float(free) < LIMIT


@pytest.mark.parametrize("options", [
    "'--elements-per-diameter', '27'",
    "'--model', 'bem-fft', '--cells-per-diameter', '256'"])
def test_a_solve_beyond_the_limit_is_refused_before_it_starts(options):
    """paper-fig3-dense at P = 27 needs ~2.8 GiB: under ulimit -v 2000000 it once passed the
    check (the machine had 20 GiB free) and died out of memory after 16 s; bem-fft at
    N = 256 (~15 GiB) died after 32 s."""
    out = _run("import sys; from validation.cli import main; sys.exit(main(['solve', "
               f"'--scene', 'paper-fig3-dense', {options}]))")
    assert out.returncode == 2, out.stderr
    assert "ulimit -v" in out.stderr and "Traceback" not in out.stderr


def test_unlimited_process_quotes_the_machine():
    free, what = memory_limit()
    if resource.getrlimit(resource.RLIMIT_AS)[0] != resource.RLIM_INFINITY:
        pytest.skip("this test process runs under an address-space limit")
    assert free > 0 and what
    assert memory_short(0.5 * MEMORY_SHARE * free) is None
    assert what in memory_short(2.0 * free)


@pytest.mark.parametrize("solver", ["dense", "fft"])
def test_a_grid_too_large_is_refused_before_any_compliance_build(monkeypatch, solver):
    """The elastic pillar (the default on the presets) built its compliance, 20-140 s, before
    the FFT model refused the grid by its memory: the refusal comes first."""
    from bem_solver import _dense, _fft
    from pillar_xval.scenes import ScopeError, load_scene

    def build(*args, **kwargs):
        raise AssertionError("the compliance was built for a grid that is refused")

    monkeypatch.setattr(_fft, "scene_compliance", build)
    monkeypatch.setattr(_dense, "scene_compliance", build)
    monkeypatch.setattr("pillar_xval.outcome.memory.memory_limit",
                        lambda: (1e9, "a test's 1 GB"), raising=True)
    scene = load_scene("paper-fig3-dense")
    solve = ((lambda: _fft.solve_fft(scene, 256, pillars="elastic")) if solver == "fft" else
             (lambda: _dense.solve_dense(scene, 41, pillars="elastic")))
    with pytest.raises(ScopeError, match="1 GB"):
        solve()
