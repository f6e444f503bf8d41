"""The pytest plugin, run as a user runs it: the example test file through ``pytester`` in a
subprocess, with passing and with failing tolerances, rerun from the cache, and under
pytest-xdist."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import pytest

pytest_plugins = ("pytester",)

EXAMPLE = Path(__file__).resolve().parents[1] / "validation" / "examples" / "test_user_checks.py"
PLUGIN = "validation.pytest_plugin"


def _plugin_args() -> list[str]:
    """Installed, the entry point loads the plugin; from a bare checkout, name it."""
    names = {ep.value for ep in importlib.metadata.entry_points(group="pytest11")}
    return [] if PLUGIN in names else ["-p", PLUGIN]


def _run(pytester, *args):
    return pytester.runpytest_subprocess(*_plugin_args(), *args)


def test_the_entry_point_names_the_plugin():
    """Installing the toolkit enables the plugin (skipped where it is not installed)."""
    eps = [ep for ep in importlib.metadata.entry_points(group="pytest11")
           if ep.value == PLUGIN]
    if not eps:
        pytest.skip("pillar-xval is not installed in this environment")
    assert eps[0].load().__name__ == PLUGIN


def test_example_passes_then_a_rerun_solves_nothing(pytester):
    pytester.makepyfile(test_user_checks=EXAMPLE.read_text())
    first = _run(pytester)
    first.assert_outcomes(passed=2)
    first.stdout.fnmatch_lines(["*pillar-xval checks*", "*3 checks, 0 failed*",
                                "*xval cases: 3 solved, 0 from the cache*"])
    again = _run(pytester)
    again.assert_outcomes(passed=2)
    again.stdout.fnmatch_lines(["*xval cases: 0 solved, 3 from the cache*"])
    fresh = _run(pytester, "--xval-fresh")
    fresh.stdout.fnmatch_lines(["*xval cases: 3 solved, 0 from the cache*"])


def test_a_tight_tolerance_fails_with_the_whole_story(pytester):
    text = EXAMPLE.read_text()
    assert "RTOL_BEM_FEM = 0.03" in text
    pytester.makepyfile(test_user_checks=text.replace("RTOL_BEM_FEM = 0.03",
                                                      "RTOL_BEM_FEM = 0.005"))
    result = _run(pytester)
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines([
        "*assert_close: 1 of 1 quantities differ beyond the tolerance*",
        "*F_T: actual * N (bem, elements_per_diameter 11), expected * N (fem-axisym, "
        "mesh_size 2): difference -* N (-*%) exceeds * N (rtol 0.005; source: dense BEM "
        "P = 11 against fem-axisym, measured 2.2 %)*",
        "*test_bem_against_fem_on_one_pillar*assert_close*F_T*rtol 0.005*FAIL*",
    ])


def test_xdist_workers_never_solve_one_case_twice(pytester):
    pytest.importorskip("xdist")
    body = ('from validation.testing import assert_close\n'
            'def test_same(xval):\n'
            '    r = xval.run("bem", xval.scene("hertz"), elements_per_diameter=7)\n'
            '    assert_close(r, r.total_force_N, "F_T", rtol=1e-12, source="itself")\n')
    pytester.makepyfile(**{f"test_same_{i}": body for i in range(4)})
    result = _run(pytester, "-n", "2")
    result.assert_outcomes(passed=4)
    result.stdout.fnmatch_lines(["*4 checks, 0 failed*",
                                 "*xval cases: 1 solved, 3 from the cache*"])


def test_an_option_the_model_does_not_take_is_a_usage_error(pytester):
    """Dropped silently before: the solve ran at its default, cached under a key naming the
    option."""
    body = ('def test_mesh_size(xval):\n'
            '    xval.run("bem", xval.scene("hertz"), mesh_size=2.0)\n'
            'def test_misspelt(xval):\n'
            '    xval.run("bem", xval.scene("hertz"), elements_per_diametre=7)\n'
            'def test_bad_value(xval):\n'
            '    xval.run("bem", xval.scene("hertz"), elements_per_diameter=1)\n'
            'def test_flat_elastic(xval):\n'
            '    xval.converge("bem", xval.scene("hertz"), pillars="elastic")\n')
    pytester.makepyfile(test_options=body)
    result = _run(pytester)
    result.assert_outcomes(failed=4)
    result.stdout.fnmatch_lines([
        "*UsageError: xval.run('bem'): bem: unknown option(s) 'mesh_size'; it takes*",
        "*UsageError: xval.run('bem'): bem: unknown option(s) 'elements_per_diametre'*",
        "*UsageError: xval.run('bem'): bem: elements_per_diameter = 1: allowed range*",
        "*UsageError: xval.converge('bem'): bem: pillars = 'elastic': the scene is flat*",
    ])
    result.stdout.no_fnmatch_line("*xval cases: *solved*")  # nothing was solved
