"""The CLI fuzz widened: sweep specs, ``plan`` and ``figures`` inputs, odd
``--out`` paths, environment oddities and a real ``ulimit -v``, one folder shared by two
commands, and edited case files.

Every case: an exit status in {0, 1, 2, 3, 130, 143}, exactly one line on stderr for a
failure, never a traceback, and no NaN or infinity in any JSON or CSV file written.  Runs go
in-process on the fake models (tests/fakes.py) with the serial executor, or with --dry-run;
the few that need a process of their own (environment, ulimit) use the real dense BEM on a
flat scene at P = 5.  The whole file takes seconds.
"""

from __future__ import annotations

import json
import os
import random
import re
import resource
import subprocess
import sys
from pathlib import Path

import pytest

EXITS = {0, 1, 2, 3, 130, 143}
LINE = re.compile(r"pillar-xval( [\w-]+)?: (error|failure|not converged|interrupted|"
                  r"terminated)\b")
SEED = 20261125
# A JSON or CSV value that is not a finite number.
NONFINITE = re.compile(r"(?i)(?<![\w.])-?(nan|inf|infinity)(?![\w])")


def check(code: int, out: str, err: str, *folders) -> str:
    """The failure policy on one outcome; returns the message line ('' for exit 0)."""
    assert "Traceback" not in err and "Traceback" not in out, err[-2000:]
    assert code in EXITS, (code, err[-2000:])
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("[")]
    for folder in folders:
        assert_finite_files(folder)
    if code == 0:
        assert not any(LINE.match(ln) for ln in lines), err
        return ""
    assert len(lines) == 1, (code, err[-2000:])
    assert LINE.match(lines[0]) and len(lines[0]) < 600, lines[0]
    return lines[0]


def assert_finite_files(folder) -> None:
    folder = Path(folder)
    if not folder.is_dir():
        return
    for path in folder.rglob("*"):
        if path.is_file() and path.suffix in (".json", ".csv"):
            text = path.read_text(errors="replace")
            bad = NONFINITE.search(text)
            assert bad is None, f"{path}: {text[max(0, bad.start() - 80):bad.end() + 40]}"


# --- sweep specs --------------------------------------------------------------------------
VALID_SPEC = """name = "fz"
scene = "hertz"
on_invalid = "skip"

[grid]
"load.indentation_um" = [0.2, 0.3]

[[models]]
name = "bem"
elements_per_diameter = 5
"""
SPEC_VALUES = ["nan", "inf", "-inf", "-1", "0", "1e400", "1e-320", '"text"', "[]", "[[1]]",
               "{a = 1}", "true", "9" * 400, "[nan]", "[1e400]", "[-1, 0.2]", "[0.2, 0.2]",
               "{ log = [0, 1], num = 3 }", "{ linear = [0.1, 0.3], num = -1 }",
               "{ linear = [0.1, 0.3], num = 1000000000 }", "{ log = [0.1, nan], num = 3 }",
               '"../../etc/evil"', '"ü Φ name"', '""', '"a/b"', "[0.1, 0.2, 0.3]",
               "{ log = [0.05, 1.9], num = 200 }", "1.5", "3"]
SPEC_LINES = ['colour = "red"', "[extra]", '"lens.colour" = [1]', '"nope" = [1]',
              'foo = 1', '"pillars.surface_fraction" = [0.1]', "[[models]]",
              'name = "nope"', 'name = "bem-fft"', "cells_per_diameter = 8",
              '"lens.E_Pa" = [1e6, 1e300]', '"load.indentation_um" = [0.2]']


def _spec_text(rng: random.Random) -> str | bytes:
    """A mutation of a valid spec: a value replaced, a line dropped or added, the text cut
    short, a duplicated table, bytes that are not text."""
    lines = VALID_SPEC.splitlines()
    kind = rng.choice(["value", "value", "value", "drop", "add", "add", "cut", "bytes",
                       "empty", "toml"])
    if kind == "bytes":
        return bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200)))
    i = rng.randrange(len(lines))
    if kind == "value" and "=" in lines[i]:
        lines[i] = lines[i].split("=")[0] + "= " + rng.choice(SPEC_VALUES)
    elif kind == "drop":
        del lines[i]
    elif kind == "add":
        lines.insert(i + 1, rng.choice(SPEC_LINES))
    elif kind == "cut":
        lines = lines[:i]
    elif kind == "empty":
        lines = []
    elif kind == "toml":
        lines.insert(i, rng.choice(["[[", "a = ", "= 1", "[grid]", "x = [1, 2", '"\\q" = 1']))
    return "\n".join(lines) + "\n"


def test_fuzz_sweep_specs(fakes, tmp_path, cli):
    """Seeded bad specs through `sweep` (dry run, and a real run on the fake BEM)."""
    rng = random.Random(SEED)
    codes = {}
    for k in range(80):
        spec = tmp_path / f"spec-{k}.toml"
        text = _spec_text(rng)
        spec.write_bytes(text if isinstance(text, bytes) else text.encode())
        out = tmp_path / f"o-{k}"
        argv = ["sweep", spec, "--out", out, "--executor", "serial"]
        if rng.random() < 0.6:
            argv.append("--dry-run")
        if rng.random() < 0.3:
            argv.append("--json")
        code, stdout, err = cli(*argv)
        check(code, stdout, err, out)
        codes[code] = codes.get(code, 0) + 1
        # nothing escapes the folder the user named
        assert not (tmp_path.parent / "etc").exists()
        if "--json" in argv and code == 0:
            json.loads(stdout)
    assert codes.get(0, 0) > 5 and codes.get(2, 0) > 20, codes


# --- plan and figures inputs --------------------------------------------------------------
BAD = ["-1", "0", "nan", "inf", "1e400", "1e-400", "abc", "", " ", "9" * 400, "0.5", "1",
       "2", "1e-3", "5", "41", "42", "3", "0x10", "-0", "1,5"]


def test_fuzz_plan(tmp_path, cli):
    from pillar_xval.scenes import preset_names

    rng = random.Random(SEED + 1)
    for k in range(40):
        argv = ["plan", "--scene", rng.choice(preset_names() + ["nope", str(tmp_path)])]
        for _ in range(rng.randrange(0, 3)):
            opt = rng.choice(["--tolerance", "--quantities", "--budget", "--set"])
            value = {"--quantities": rng.choice(["F_T", "nope", "", "F_T,F_T", ",",
                                                 "a,A,sigma0,F_T", "sigma0"]),
                     "--set": rng.choice(["pillars.E_Pa=1e9", "lens.nu=2", "load.x=1",
                                          "load.indentation_um=nan", "pillars.rigid=true",
                                          "pillars.surface_fraction=0.5"])
                     }.get(opt, rng.choice(BAD))
            argv += [opt, value]
        if rng.random() < 0.3:
            argv.append("--json")
        code, out, err = cli(*argv)
        check(code, out, err)
        if code == 0 and "--json" in argv:
            json.loads(out)


def test_fuzz_figures_inputs(tmp_path, cli, monkeypatch):
    """figures' options: every input is accepted or refused before any work (the study is
    replaced by a stub: an accepted input would start minutes of solves)."""
    from validation.studies import figures

    started = []

    def stub(out, grid, model, engine, **kw):
        started.append((grid.name, model))
        return {"timing": {"unique_cases": 0, "cases_computed": 0, "threshold_solves": 0,
                           "total_s": 0.0, "scenes_s": 0.0, "threshold_bisection_s": 0.0,
                           "analysis_and_plots_s": 0.0, "executor": "serial"}, "failed": []}

    monkeypatch.setattr(figures, "run_figures", stub)
    rng = random.Random(SEED + 2)
    a_file = tmp_path / "a-file"
    a_file.write_text("x")
    for k in range(40):
        argv = ["figures", "--executor", "serial"]
        for _ in range(rng.randrange(0, 4)):
            opt = rng.choice(["--model", "--elements-per-diameter", "--workers", "--out",
                              "--quick", "--executor"])
            if opt == "--quick":
                argv.append(opt)
                continue
            value = {"--model": rng.choice(["bem", "bem-fft", "fem-3d", "nope", ""]),
                     "--out": rng.choice([str(a_file), str(a_file / "x"), "/dev/null",
                                          str(tmp_path / "ü Φ out"), str(tmp_path / "o k")]),
                     "--executor": rng.choice(["serial", "pool", "dask", "nope"])
                     }.get(opt, rng.choice(BAD))
            argv += [opt, value]
        if "--out" not in argv:
            argv += ["--out", tmp_path / f"f-{k}"]
        code, out, err = cli(*argv)
        check(code, out, err)
    assert started  # some inputs were accepted


# --- --out paths ------------------------------------------------------------------------
@pytest.mark.parametrize("command", ["solve", "converge", "sweep"])
def test_odd_out_paths(fakes, tmp_path, cli, command):
    spec = tmp_path / "s.toml"
    spec.write_text(VALID_SPEC)
    argv = {"solve": ["solve", "--scene", "hertz"],
            "converge": ["converge", "--scene", "hertz", "--levels", "2", "--executor",
                         "serial"],
            "sweep": ["sweep", spec, "--executor", "serial"]}[command]
    a_file = tmp_path / "plain file"
    a_file.write_text("x")
    refused = ["/dev/null", a_file, a_file / "below", "/proc/version/sub", "/sys/kernel/xval",
               "/proc/self/xval"]
    for out in refused:
        code, stdout, err = cli(*argv, "--out", out)
        line = check(code, stdout, err)
        assert code == 2 and "--out" in line, line
    for name in ("with space", "ü Φ ζ 目录", "tab\tand'quote\"", "-leading-dash", "a" * 200):
        out = tmp_path / name
        code, stdout, err = cli(*argv, "--out", out)
        check(code, stdout, err, out)
        assert code == 0, err
        assert any(out.iterdir())


def test_a_read_only_out_is_one_line(fakes, tmp_path, cli):
    if os.geteuid() == 0:
        pytest.skip("root writes into a read-only folder (/proc and /sys cover it above)")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        for out in (ro, ro / "sub"):
            code, stdout, err = cli("solve", "--scene", "hertz", "--out", out)
            check(code, stdout, err)
            assert code in (2, 3)
    finally:
        ro.chmod(0o755)


# --- environment oddities and a real ulimit -v --------------------------------------------
ROOT = Path(__file__).resolve().parents[1]


def _cli_process(argv, env_changes=None, unset=(), limit=None, timeout=120):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    for key in unset:
        env.pop(key, None)
    env.update(env_changes or {})

    def limited():
        if limit is not None:
            resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    proc = subprocess.run([sys.executable, "-m", "validation.cli", *map(str, argv)],
                          capture_output=True, env=env, preexec_fn=limited, timeout=timeout,
                          cwd=ROOT)
    return (proc.returncode, proc.stdout.decode("utf-8", "replace"),
            proc.stderr.decode("utf-8", "replace"))


SOLVE = ["solve", "--scene", "hertz", "--elements-per-diameter", "5"]


@pytest.mark.parametrize("env, unset", [
    ({}, ("HOME",)),
    ({"LANG": "C", "LC_ALL": "C"}, ()),
    ({"PYTHONIOENCODING": "ascii"}, ()),
    ({"PILLAR_XVAL_DEBUG": "maybe\u00fc"}, ()),
    ({"PILLAR_XVAL_DEBUG": "0", "TMPDIR": "/nonexistent-tmp"}, ()),
    ({"MPLCONFIGDIR": "/proc/version", "XDG_CACHE_HOME": "/dev/null"}, ("HOME",)),
])
def test_environment_oddities(tmp_path, env, unset):
    """Odd environments: the result is written (into a folder with a non-ASCII name) and
    printed, or one line; never a traceback.  PYTHONIOENCODING=ascii once made `solve`
    exit 4 after its work, on printing the folder's name."""
    out = tmp_path / "é out"
    code, stdout, err = _cli_process([*SOLVE, "--out", out], env, unset)
    check(code, stdout, err, out)
    assert code == 0, err
    assert (out / "result.json").is_file() and "written to" in stdout
    code, stdout, err = _cli_process(["solve", "--scene", "hertz", "--set", "lens.nu=ü"], env,
                                     unset)
    assert check(code, stdout, err) and code == 2


def _openblas_gave_up(code: int, err: str) -> bool:
    """OpenBLAS, short of address space for its threads' buffers, prints its own line and
    ends the process from C (exit 1, or a signal) where Python cannot answer: whether it
    does at a given limit depends on the machine's cores and the memory layout."""
    return err.startswith("OpenBLAS") and len(err.strip().splitlines()) == 1


# 300 MB (too little to load the libraries) is left to the in-process test below: under a
# real limit that tight, OpenBLAS itself ends the process, or hangs past two minutes spawning
# its threads (measured on this machine), before Python can answer.
@pytest.mark.parametrize("limit_mb, codes", [(2000, {0})])
def test_a_real_ulimit(tmp_path, limit_mb, codes):
    """Under `ulimit -v`: enough, a solve is done, and one too big for the limit refused with
    one line."""
    out = tmp_path / "u"
    code, stdout, err = _cli_process([*SOLVE, "--out", out], limit=limit_mb << 20)
    if limit_mb < 1000 and _openblas_gave_up(code, err):
        pytest.skip(f"OpenBLAS ended the process itself under {limit_mb} MB: {err.strip()}")
    line = check(code, stdout, err, out)
    assert code in codes, err
    if code == 3:
        assert "ulimit -v" in line
    if limit_mb >= 1000:
        code, stdout, err = _cli_process(["solve", "--scene", "paper-fig3-dense",
                                          "--elements-per-diameter", "27", "--pillars",
                                          "hooke"],
                                         limit=limit_mb << 20)
        assert check(code, stdout, err) and code == 2 and "ulimit -v" in err


@pytest.mark.parametrize("exc", [
    ImportError("/x/_fblas.so: failed to map segment from shared object"),
    MemoryError(), SystemError("error return without exception set")])
def test_a_library_that_cannot_load_is_one_line(monkeypatch, cli, exc):
    """What a tight `ulimit -v` does to the loading of numpy and scipy, in-process: one line,
    exit 3, naming the limit (once a traceback from the console script's import)."""
    import validation.cli as cli_module

    def fail(name):
        raise exc

    monkeypatch.setattr(cli_module.importlib, "import_module", fail)
    code, out, err = cli("solve", "--scene", "hertz")
    line = check(code, out, err)
    assert code == 3 and "out of memory loading the libraries" in line
    assert "ulimit -v" in line


# --- one folder shared by two commands ----------------------------------------------------
def _argv(command, spec):
    return {"solve": ["solve", "--scene", "hertz", "--elements-per-diameter", "5"],
            "converge": ["converge", "--scene", "hertz", "--levels", "2", "--executor",
                         "serial"],
            "compare": ["compare", "--scene", "hertz", "--levels", "2", "--no-render",
                        "--executor", "serial"],
            "tradeoff": ["tradeoff", "--scene", "hertz", "--models", "bem", "--levels", "3",
                         "--repeats", "1", "--executor", "serial"],
            "sweep": ["sweep", spec, "--executor", "serial"]}[command]


@pytest.mark.parametrize("first, second", [("compare", "converge"), ("sweep", "solve"),
                                           ("solve", "tradeoff"), ("tradeoff", "compare"),
                                           ("converge", "sweep")])
def test_one_folder_shared_by_two_commands(fakes, tmp_path, cli, first, second):
    spec = tmp_path / "s.toml"
    spec.write_text(VALID_SPEC)
    out = tmp_path / "shared"
    code, stdout, err = cli(*_argv(first, spec), "--out", out)
    check(code, stdout, err, out)
    assert code == 0, err
    before = sorted(p.name for p in out.iterdir())
    code, stdout, err = cli(*_argv(second, spec), "--out", out)
    line = check(code, stdout, err, out)
    assert code == 2 and f"`pillar-xval {first}`" in line, line
    assert sorted(p.name for p in out.iterdir()) == before  # nothing mixed in
    code, stdout, err = cli(*_argv(first, spec), "--out", out)  # its own command replaces it
    check(code, stdout, err, out)
    assert code == 0


# --- edited case files --------------------------------------------------------------------
def _edits(text: str, rng: random.Random) -> list[tuple[str, str | bytes]]:
    from test_engine import _set

    record = json.loads(text)

    def changed(path, value):
        return _set(path, value)(text)

    edits = [("x1.1 centre", changed(["result", "centre_pressure_Pa"], lambda p: 1.1 * p)),
             ("x3 radius", changed(["result", "contact_radius_m"], lambda a: 3 * a)),
             ("nan force", json.dumps(record).replace(
                 json.dumps(record["result"]["total_force_N"]), "NaN", 1)),
             ("string force", changed(["result", "total_force_N"], "12")),
             ("null result", changed(["result"], None)),
             ("cut", text[: len(text) // 2]),
             ("empty", ""),
             ("bytes", bytes(rng.randrange(256) for _ in range(64))),
             ("list", "[1, 2, 3]"),
             ("huge number", changed(["result", "centre_pressure_Pa"], 1e308)),
             ("other key", changed(["key"], "0" * 16)),
             ("deep", "[" * 100000 + "]" * 100000)]
    return edits


def test_edited_case_files_are_recomputed_not_used(fakes, tmp_path, cli):
    """Every edit of a cached case (values scaled, NaN, types, cut, binary, nesting) is
    recomputed: the table keeps the solver's values, and the outcome is the failure policy's."""
    rng = random.Random(SEED + 3)
    spec = tmp_path / "s.toml"
    spec.write_text(VALID_SPEC)
    out = tmp_path / "o"
    code, stdout, err = cli("sweep", spec, "--out", out, "--executor", "serial", "--json")
    check(code, stdout, err, out)
    rows = json.loads(stdout)["rows"]
    records = sorted((out / "cases").rglob("*.json"))
    records = [p for p in records if "result" in p.read_text(errors="replace")]
    assert records
    pristine = {p: p.read_text() for p in records}
    for label, edited in _edits(pristine[records[0]], rng):
        for p in records:
            if isinstance(edited, bytes):
                p.write_bytes(edited)
            else:
                p.write_text(edited)
        code, stdout, err = cli("sweep", spec, "--out", out, "--executor", "serial", "--json")
        check(code, stdout, err, out)
        assert code == 0, (label, err)
        again = json.loads(stdout)["rows"]
        for a, b in zip(rows, again):
            for key in ("centre_pressure_Pa", "contact_radius_m", "total_force_N"):
                if key in a:
                    assert a[key] == b[key], (label, key)
        assert "recomputing" in err, label
