"""What a hostile or careless input once got through silently: each is now refused with one
line naming the option, or handled at its root."""

from __future__ import annotations

from pathlib import Path

import pytest

from scenes import InputError
from validation.engine import Engine

SPEC = Path(__file__).resolve().parents[1] / "validation" / "examples" / "sweep-phi-zeta.toml"


@pytest.mark.parametrize("kwargs, message", [
    ({"executor": "serial", "workers": 4}, "--executor serial runs every case"),
    ({"executor": "pool", "workers": 1000}, "allowed range is [1, "),
    ({"executor": "pool", "workers": 0}, "allowed range is [1, "),
    ({"executor": "pool", "scheduler": "tcp://127.0.0.1:1"}, "drop one of the two"),
    ({"executor": None, "scheduler": "tcp://127.0.0.1:1", "workers": 2}, "its own workers"),
    ({"executor": "threads"}, "allowed: serial, pool, dask"),
])
def test_contradicting_executor_options_are_refused(kwargs, message):
    with pytest.raises(InputError) as err:
        Engine(**kwargs)
    assert message in str(err.value)


def test_a_scheduler_alone_means_dask_and_no_executor_means_a_pool():
    assert Engine(None, scheduler="tcp://127.0.0.1:1").executor_name == "dask"
    assert Engine(None).executor_name == "pool"
    assert Engine("serial").parallel == 1 and Engine(None, workers=3).parallel == 3


@pytest.mark.parametrize("extra", [["--workers", "0"], ["--executor", "serial", "--workers", "4"],
                                   ["--executor", "pool", "--scheduler", "tcp://127.0.0.1:1"]])
def test_a_dry_run_checks_the_engine_options_as_a_run_does(cli, tmp_path, extra):
    code, _, err = cli("sweep", SPEC, "--dry-run", "--out", tmp_path, *extra)
    assert code == 2 and err.count("\n") == 1 and "error:" in err
