"""The CLI fuzz grown by what it reads and did not write: sweep grids too large to hold.
Each case: the failure policy (an exit status, one line, no
traceback), before anything is built or planned.
"""

from __future__ import annotations

import json
import time

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
    from validation.planner import tables

    reads = []
    load = tables.load_data
    monkeypatch.setattr(tables, "load_data", lambda *a: reads.append(1) or load(*a))
    spec = tmp_path / "grid.toml"
    spec.write_text(ONE_AXIS.format(num=100_000, num2=1))
    start = time.perf_counter()
    code, out, err = cli("sweep", spec, "--out", tmp_path / "o", "--dry-run", "--json")
    took = time.perf_counter() - start
    assert code == 0, err
    assert json.loads(out)["points"] == 100_000 and len(reads) == 1
    assert took < 30.0, f"{took:.1f} s"

