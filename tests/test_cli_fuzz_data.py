"""The CLI fuzz grown by what it reads and did not write: sweep grids too large to hold, and
damaged planner data.  Each case: the failure policy (an exit status, one line, no
traceback), before anything is built or planned.
"""

from __future__ import annotations

import json
import math
import shutil
import time

import pytest

from test_cli_fuzz_wide import _cli_process, check

TWO_HUGE_AXES = """scene = "paper-fig3-sparse"
[grid]
"load.indentation_um" = { log = [0.05, 1.9], num = 1000000000 }
"pillars.surface_fraction" = { linear = [0.01, 0.9], num = 1000000000 }
[[models]]
name = "bem"
"""


def test_a_grid_whose_axes_cannot_fit_is_refused_before_it_is_built(tmp_path):
    """`num = 1000000000` on two axes with --dry-run once grew to 22.7 GB and was killed by
    the kernel without a word.  (Under a 3 GiB address-space limit, so that a regression
    fails here instead of taking the machine's memory.)"""
    spec = tmp_path / "huge.toml"
    spec.write_text(TWO_HUGE_AXES)
    for extra in (["--dry-run"], []):
        code, out, err = _cli_process(["sweep", spec, "--out", tmp_path / "o", *extra],
                                      limit=3 << 30, timeout=60)
        line = check(code, out, err)
        assert code == 2 and "its axes hold 2,000,000,000 values" in line, err


ONE_AXIS = """scene = "paper-fig3-sparse"
on_invalid = "skip"
[grid]
"load.indentation_um" = {{ log = [0.05, 1.9], num = {num} }}
"pillars.surface_fraction" = {{ linear = [0.01, 0.5], num = {num2} }}
[[models]]
name = "bem"
elements_per_diameter = [5, 7]
"""


def test_a_run_that_cannot_hold_its_cases_is_refused_and_its_dry_run_is_not(fakes, tmp_path,
                                                                            cli):
    """10^8 points x 2 option sets: a run would hold 2e8 cases (terabytes); refused in one
    line before any case is built.  Its dry run samples the grid and says what it costs."""
    spec = tmp_path / "big.toml"
    spec.write_text(ONE_AXIS.format(num=10_000, num2=10_000))
    code, out, err = cli("sweep", spec, "--out", tmp_path / "o", "--executor", "serial")
    line = check(code, out, err)
    assert code == 2 and "100,000,000 points give 200,000,000 cases" in line
    assert fakes == [] and not (tmp_path / "o").exists()
    code, out, err = cli("sweep", spec, "--out", tmp_path / "o", "--dry-run", "--json")
    check(code, out, err)
    assert code == 0 and json.loads(out)["points"] == 10**8


def test_a_dry_run_of_1e5_points_takes_seconds(tmp_path, cli, monkeypatch):
    """A dry run of 10^5 points once took 136 s: a quadratic check for repeated values on
    the axis, and the planner's data read again for every sampled case.  The bound, 30 s, is
    over 15 times the 1.7 s it takes now in a fresh process (make bench-sweep, at a load
    average of 10) and a fifth of what the quadratic check took alone."""
    import importlib

    plan_module = importlib.import_module("validation.planner.plan")
    reads = []
    load = plan_module.load_data
    monkeypatch.setattr(plan_module, "load_data", lambda *a: reads.append(1) or load(*a))
    monkeypatch.setattr(plan_module, "_DATA", {})
    spec = tmp_path / "grid.toml"
    spec.write_text(ONE_AXIS.format(num=100_000, num2=1))
    start = time.perf_counter()
    code, out, err = cli("sweep", spec, "--out", tmp_path / "o", "--dry-run", "--json")
    took = time.perf_counter() - start
    assert code == 0, err
    assert json.loads(out)["points"] == 100_000 and len(reads) == 1
    assert took < 30.0, f"{took:.1f} s"


# --- damaged planner data -------------------------------------------------------------------
def _set(path, value):
    """A mutation that sets the entry at ``path`` (keys and indices) to ``value``."""
    def mutate(doc):
        for key in path[:-1]:
            doc = doc[key]
        doc[path[-1]] = value
    return mutate


def _drop(path):
    def mutate(doc):
        for key in path[:-1]:
            doc = doc[key]
        del doc[path[-1]]
    return mutate


# (file, mutation of its document or of its text, the entry the line must name)
DAMAGED = {
    "a missing key": ("error_models.json", _drop(["candidates"]), "'candidates' is missing"),
    "truncated JSON": ("error_models.json", lambda text: text[:len(text) // 2],
                       "not valid JSON"),
    "a table without errors": ("error_models.json", _drop(["tables", 3, "errors"]),
                               "tables[3]: the key 'errors' is missing"),
    "a NaN cost coefficient": ("cost_models.json", _set(["models", "bem", "coef", 1], math.nan),
                               "models.bem.coef[1] = nan"),
    "a negative cost coefficient": ("cost_models.json",
                                    _set(["models", "bem-fft", "coef", 0], -0.01),
                                    "models.bem-fft.coef[0] = -0.01"),
    "a negative variant factor": ("cost_models.json",
                                  _set(["variants", "bem pillars=elastic", "factor", "default"],
                                       -1.5), "factor.default = -1.5"),
    "a negative margin_scale": ("error_models.json", _set(["policy", "margin_scale"], -1.0),
                                "policy.margin_scale = -1.0"),
    "a NaN error": ("error_models.json", _set(["tables", 5, "errors", "sigma0", 0], math.nan),
                    "tables[5].errors.sigma0[0] = nan"),
    "an error table too short": ("error_models.json", _set(["tables", 5, "errors", "F_T"], [0.1]),
                                 "tables[5].errors.F_T: has 1 values"),
    "a table of an unknown feature": ("error_models.json",
                                      _set(["tables", 5, "features", 0], "colour"),
                                      "tables[5].features[0] = 'colour'"),
}


@pytest.mark.parametrize("damage", DAMAGED)
def test_damaged_planner_data_is_one_line_naming_the_file_and_the_entry(tmp_path, cli,
                                                                        monkeypatch, damage):
    """A missing key, truncated JSON or a table without errors once exited 4 naming no file;
    a NaN cost coefficient failed only after a 30 s plan; a negative cost, a negative
    margin_scale or NaN errors were read and changed the plans."""
    import importlib

    from validation.planner import tables

    plan_module = importlib.import_module("validation.planner.plan")

    name, mutate, entry = DAMAGED[damage]
    for n in ("error_models.json", "cost_models.json"):
        shutil.copyfile(tables.data_dir() / n, tmp_path / n)
    path = tmp_path / name
    try:
        mutate_text = mutate(path.read_text())
    except (TypeError, AttributeError):
        mutate_text = None
    if isinstance(mutate_text, str):
        path.write_text(mutate_text)
    else:
        doc = json.loads(path.read_text())
        mutate(doc)
        path.write_text(json.dumps(doc))
    monkeypatch.setattr(tables, "data_dir", lambda: tmp_path)
    monkeypatch.setattr(plan_module, "_DATA", {})
    for argv in (["plan", "--scene", "paper-fig3-sparse", "--json"],
                 ["solve", "--model", "auto", "--scene", "single-pillar", "--json"]):
        start = time.perf_counter()
        code, out, err = cli(*argv)
        line = check(code, out, err)
        assert code == 2 and str(path) in line and entry in line, line
        assert time.perf_counter() - start < 10.0   # before any planning (a plan took 30 s)
