"""The floor benchmark's command line (validation/bench/floor.py)."""

from __future__ import annotations

import pytest

from validation.bench import floor as bench


@pytest.mark.parametrize("argv, says", [(["--only", "perfx"], "--only = 'perfx'"),
                                        (["--only", ","], "choose parts among"),
                                        (["--repeats", "0"], "--repeats = 0")])
def test_bad_arguments_exit_2_naming_the_value(tmp_path, capsys, argv, says):
    with pytest.raises(SystemExit) as stop:
        bench.main(["--out", str(tmp_path)] + argv)
    assert stop.value.code == 2
    assert says in capsys.readouterr().err
    assert not (tmp_path / "bench_floor.json").exists()
