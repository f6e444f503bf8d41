"""The CLI's failure policy, proved by a seeded fuzz test and by each reported case.

Every run goes in-process through ``validation.cli.main`` with an argv list, on the fake
models of tests/fakes.py (or the real dense BEM at a tiny resolution), with the serial
executor, so the whole file runs in seconds.  Each outcome must be exit 0, 1, 2, 3 (or 4, a
bug, which the test refuses) with the right kind of one-line message on stderr and never a
traceback.
"""

from __future__ import annotations

import json
import random
import re
import subprocess
import sys

import pytest

from pillar_xval.outcome import package_version
from pillar_xval.scenes import ToolError, load_scene, preset_names, scene_to_toml

# The one line of each outcome (progress lines on stderr start with "[").
KIND = {1: "not converged", 2: "error", 3: "failure", 4: "internal error", 130: "interrupted"}
SEED = 20240610
# The scene files the fuzz mutates: a preset written out as a file (every table and key).
VALID_SCENE = scene_to_toml(load_scene("paper-fig3-sparse"))


def outcome(cli, *argv) -> tuple[int, str, str]:
    """Run the CLI and check the failure policy on its outcome; returns (code, stdout, line)
    where line is the message line on stderr ('' for exit 0)."""
    code, out, err = cli(*argv)
    assert "Traceback" not in err and "Traceback" not in out, err
    assert code in (0, 1, 2, 3), (argv, code, err)
    lines = [ln for ln in err.splitlines() if ln and not ln.startswith("[")]
    if code == 0:
        assert not any(": error:" in ln or ": failure:" in ln for ln in lines), err
        return code, out, ""
    assert len(lines) == 1, (argv, err)
    assert re.match(rf"pillar-xval( [\w-]+)?: {KIND[code]}: ", lines[0]), (argv, lines[0])
    assert len(lines[0]) < 600
    return code, out, lines[0]


# --- the reported cases -------------------------------------------------------------------------
@pytest.mark.parametrize("argv, code, fragment", [
    # a 400-digit integer, a subnormal modulus: the scene's ranges, one line
    (["solve", "--scene", "single-pillar", "--set", "lens.E_Pa=" + "9" * 400], 2,
     "(400 characters): allowed range is [0.001, 1e+16] Pa"),
    (["solve", "--scene", "single-pillar", "--set", "pillars.E_Pa=1e-320"], 2, "allowed range"),
    (["solve", "--model", "fem-axisym", "--scene", "single-pillar", "--set",
      "pillars.E_Pa=1e-310"], 2, "allowed range"),
    (["solve", "--scene", "single-pillar", "--set", "pillars.diameter_um=1e-9"], 2,
     "pillars.diameter_um=1e-9"),
    (["solve", "--scene", "single-pillar", "--set", "lens.nu=0.5000001"], 2, "0.5000001"),
    (["solve", "--scene", "single-pillar", "--set", "load.indentation_um=0_3"], 2,
     "decimal number"),
    (["solve", "--scene", "paper-fig3-sparse", "--set", "pillars.pitch_um=20", "--set",
      "pillars.surface_fraction=0.1"], 2, "not both"),
    (["solve", "--scene", "paper-fig3-sparse", "--set", "pillars.surface_fraction=0.9069"], 0,
     ""),
    (["solve", "--scene", "single-pillar", "--set", "substrate.nu=0.4999"], 0, ""),
    (["solve", "--scene", "single-pillar", "--set", "pillars.rigid=true", "--set",
      "pillars.rigid=false"], 0, ""),
    # options that do not apply to the chosen model are refused
    (["solve", "--scene", "hertz", "--model", "bem", "--mesh-size", "0.5"], 2,
     "--mesh-size 0.5: does not apply to --model bem"),
    (["solve", "--scene", "hertz", "--model", "fem-axisym", "--elements-per-diameter", "-5"],
     2, "--elements-per-diameter: -5: allowed range is [2, 400]"),
    (["solve", "--scene", "hertz", "--model", "fem-axisym", "--elements-per-diameter", "5"],
     2, "does not apply to --model fem-axisym"),
    (["solve", "--scene", "hertz", "--model", "bem-fft", "--contact", "paper"], 2,
     "--contact paper: does not apply to --model bem-fft"),
    # integers parse strictly; an option the command does not have is refused by name
    (["converge", "--scene", "hertz", "--coarsest", "5.5"], 2,
     "unrecognized arguments: --coarsest"),
    (["converge", "--scene", "hertz", "--elements-per-diameter", "5.5"], 2,
     "'5.5': expected an integer"),
    (["compare", "--scene", "hertz", "--bem-levels", "0"], 2, "unrecognized arguments: --bem-levels"),
    (["compare", "--scene", "hertz", "--fem-levels", "0"], 2, "unrecognized arguments: --fem-levels"),
    (["compare", "--scene", "hertz", "--levels", "0"], 2,
     "argument --levels: 0: allowed range is [2, 8]"),
    (["compare", "--scene", "hertz", "--elements-per-diameter", "1"], 2,
     "argument --elements-per-diameter: 1: allowed range is [2, 400]"),
    (["tradeoff", "--scene", "hertz", "--max-time", "-1"], 2,
     "argument --max-time: -1: allowed range is (0, inf)"),
    (["tradeoff", "--scene", "hertz", "--single-above", "nan"], 2,
     "argument --single-above: 'nan': expected a decimal number"),
    (["tradeoff", "--scene", "hertz", "--models", "bem,nope"], 2, "comma-separated list"),
    (["gecit", "--ratios", "inf"], 2, "argument --ratios: 'inf'"),
    (["sweep", "nowhere.toml"], 2, "no such file"),
])
def test_issue_10_cases(fakes, tmp_path, cli, argv, code, fragment):
    got, _, line = outcome(cli, *argv, *_common(argv[0], tmp_path))
    assert got == code and fragment in line, line
    if code == 2 and argv[0] != "solve":
        assert fakes == []  # refused before any solve


# --- refused before anything is solved, or said --------------------
@pytest.mark.parametrize("argv, fragment", [
    # the elastic pillar on a flat scene was run as the Hooke one, without a word
    (["solve", "--scene", "hertz", "--pillars", "elastic"], "the scene is flat"),
    (["compare", "--scene", "hertz", "--pillars", "elastic"], "--pillars elastic: the scene is "
                                                              "flat"),
    (["compare", "--scene", "hertz", "--pillars", "both"], "the scene is flat"),
    (["converge", "--scene", "hertz", "--pillars", "elastic"], "the scene is flat"),
    (["tradeoff", "--scene", "hertz", "--pillars", "elastic"], "the scene is flat"),
    # an empty entry of a list was dropped
    (["solve", "--model", "auto", "--scene", "hertz", "--quantities", "F_T,,sigma0"],
     "none empty"),
    (["plan", "--scene", "hertz", "--quantities", "F_T,,sigma0"], "none empty"),
    (["plan", "--scene", "hertz", "--quantities", ","], "none empty"),
    # fem-axisym refuses a lattice naming the model that holds it
    (["solve", "--model", "fem-axisym", "--scene", "paper-fig3-sparse"], "use fem-3d"),
])
def test_issue_35_cases(tmp_path, cli, argv, fragment):
    got, _, line = outcome(cli, *argv, *([] if argv[0] == "plan" else
                                         _common(argv[0], tmp_path)))
    assert got == 2 and fragment in line, line
    assert not (tmp_path / argv[0] / "cases").exists()  # nothing was solved


def test_the_model_line_names_the_pillar_model_and_the_hooke_error(tmp_path, cli):
    """The summary's model line read the same for both pillar models, and nothing said that
    the Hooke pillar's sigma0 is about a third low on the sparse paper scene."""
    from validation.planner.plan import hooke_error

    code, out, _ = outcome(cli, "solve", "--scene", "paper-fig3-sparse", "--pillars", "hooke",
                           "--out", tmp_path / "s")
    assert code == 0
    assert out.startswith("model            bem, Hooke pillars  (")
    expected = hooke_error(load_scene("paper-fig3-sparse"), "sigma0")
    note = next(ln for ln in out.splitlines() if ln.startswith("note "))
    assert f"sigma0 off by up to {100 * expected:.2g} %" in note
    assert note.endswith("--pillars elastic removes it")
    doc = json.loads((tmp_path / "s" / "result.json").read_text())
    assert doc["diagnostics"]["pillars"] == "hooke"
    assert doc["diagnostics"]["notes"] == [note.removeprefix("note").strip()]
    # a flat scene has no pillar model to name
    code, out, _ = outcome(cli, "solve", "--scene", "hertz", "--elements-per-diameter", "5")
    assert code == 0 and out.startswith("model            bem  (") and "note" not in out


def _common(command: str, tmp_path) -> list[str]:
    """Options that make a command cheap and observable: its own folder, serial engine."""
    if command == "solve":
        return []
    extra = ["--out", str(tmp_path / command)]
    return extra + (["--executor", "serial"] if command != "solve" else [])


def test_out_is_checked_before_any_solve(fakes, tmp_path, cli):
    a_file = tmp_path / "a-file"
    a_file.write_text("not a folder")
    for command in ("solve", "compare", "converge", "gecit", "tradeoff"):
        scene = [] if command == "gecit" else ["--scene", "single-pillar"]
        engine = [] if command == "solve" else ["--executor", "serial"]
        code, _, line = outcome(cli, command, *scene, *engine, "--out", a_file)
        assert code == 2 and "is a file, expected a folder" in line
        code, _, line = outcome(cli, command, *scene, *engine, "--out", a_file / "sub" / "dir")
        assert code == 2 and "cannot create the folder" in line
    assert fakes == [] and a_file.read_text() == "not a folder"


@pytest.mark.parametrize("command", ["lattice", "figures", "calibrate", "validate-plan",
                                     "extremes", "floor-check"])
def test_out_of_the_studies_is_checked_before_any_solve(fakes, tmp_path, cli, command):
    a_file = tmp_path / "a-file"
    a_file.write_text("not a folder")
    code, _, line = outcome(cli, command, "--executor", "serial", "--out", a_file)
    assert code == 2 and "is a file, expected a folder" in line, line
    assert fakes == [] and a_file.read_text() == "not a folder"


def test_binary_scene_file_names_the_file(tmp_path, cli):
    junk = tmp_path / "scene.toml"
    junk.write_bytes(bytes(range(256)))
    code, _, line = outcome(cli, "solve", "--scene", junk)
    assert code == 2 and str(junk) in line


def test_version_loads_nothing_of_the_toolkit():
    """``--version`` answers before the toolkit and the parser load (0.05-0.15 s against
    0.5-0.66 s when every command module was imported first): no numpy, no scenes."""
    code = ("import sys; from validation.cli import main; main(['--version']); "
            "print(sorted(m for m in ('numpy', 'pillar_xval.scenes', 'validation.registry') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.splitlines()
    assert out == [f"pillar-xval {package_version()}", "[]"]


def test_version_and_descriptions(cli):
    code, out, _ = cli("--version")
    assert code == 0 and out.strip() == f"pillar-xval {package_version()}"
    from validation.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) >= {"solve", "compare", "converge", "gecit", "tradeoff", "sweep"}
    for name, parser in sub.choices.items():
        assert parser.description and len(parser.description) > 40, name


@pytest.mark.parametrize("command", ["solve", "compare", "converge", "gecit", "tradeoff"])
def test_json_is_one_document_on_every_command(fakes, tmp_path, cli, command):
    argv = {"solve": ["--scene", "hertz", "--elements-per-diameter", "5"],
            "compare": ["--scene", "hertz", "--levels", "2", "--no-render"],
            "converge": ["--scene", "hertz", "--levels", "2"],
            "gecit": ["--ratios", "1", "--aspect", "0.5", "--levels", "1"],
            "tradeoff": ["--scene", "hertz", "--models", "bem", "--levels", "3",
                         "--repeats", "1"]}[command]
    code, out, _ = outcome(cli, command, *argv, "--json", *_common(command, tmp_path))
    assert code == 0
    json.loads(out)  # exactly one JSON document, nothing else on stdout


def test_sweep_json_and_dry_run(tmp_path, cli):
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "hertz"\n[grid]\n"load.indentation_um" = [0.2, 0.3]\n'
                    '[[models]]\nname = "bem"\nelements_per_diameter = 5\n')
    code, out, _ = outcome(cli, "sweep", spec, "--out", tmp_path / "o", "--json",
                           "--executor", "serial")
    assert code == 0 and len(json.loads(out)["rows"]) == 2
    code, out, _ = outcome(cli, "sweep", spec, "--out", tmp_path / "o", "--json", "--dry-run")
    assert code == 0 and json.loads(out)["cached"] == 2


# --- the failure policy for what happens inside a solve --------------------------------------
def _broken(exc):
    def model(scene, **options):
        raise exc

    return model


@pytest.mark.parametrize("exc, code, fragment", [
    (MemoryError("Unable to allocate 1023. MiB"), 3, "out of memory"),
    (ToolError("gmsh could not mesh: simulated"), 3, "gmsh could not mesh"),
    (OSError(28, "No space left on device"), 3, "file system"),
    (KeyboardInterrupt(), 130, "interrupted"),
])
def test_what_a_solve_raises_is_one_line(fakes, monkeypatch, cli, exc, code, fragment):
    monkeypatch.setattr(sys.modules["xval_fakes"], "fake_bem", _broken(exc))
    got, out, err = cli("solve", "--scene", "hertz")
    assert got == code and "Traceback" not in err
    (line,) = [ln for ln in err.splitlines() if not ln.startswith("[")]
    assert line.startswith(f"pillar-xval solve: {KIND[code]}") and fragment in line


def test_a_bug_is_one_line_with_a_pointer_to_its_traceback(fakes, monkeypatch, cli):
    monkeypatch.setattr(sys.modules["xval_fakes"], "fake_bem", _broken(TypeError("oops")))
    code, _, err = cli("solve", "--scene", "hertz")
    assert code == 4 and "Traceback" not in err
    assert err.strip() == ("pillar-xval solve: internal error: TypeError: oops (a bug; --debug "
                           "or PILLAR_XVAL_DEBUG=1 shows the traceback)")
    with pytest.raises(TypeError):
        cli("--debug", "solve", "--scene", "hertz")
    monkeypatch.setenv("PILLAR_XVAL_DEBUG", "1")
    with pytest.raises(TypeError):
        cli("solve", "--scene", "hertz")


def test_not_converged_is_exit_1_with_the_reason(fakes, monkeypatch, tmp_path, cli):
    from fakes import fake_bem

    def stuck(scene, **options):
        result = fake_bem(scene, **options)
        result.converged = False
        result.diagnostics["message"] = "no convergence in 3 iterations (residual 0.01 > 1e-08)"
        return result

    monkeypatch.setattr(sys.modules["xval_fakes"], "fake_bem", stuck)
    code, _, line = outcome(cli, "solve", "--scene", "hertz", "--out", tmp_path / "s")
    assert code == 1 and "no convergence in 3 iterations" in line
    assert json.loads((tmp_path / "s" / "result.json").read_text())["converged"] is False
    code, _, line = outcome(cli, "converge", "--scene", "hertz", "--levels", "2",
                            *_common("converge", tmp_path))
    assert code == 1 and "level 1 (elements_per_diameter=11)" in line


def test_real_fft_not_converged_is_stamped(tmp_path, cli):
    """The real FFT model, stopped early through the Python API, and its figure."""
    from pillar_xval.scenes import load_scene
    from bem_solver import solve_fft
    from validation.output.report import pressure_figure

    result = solve_fft(load_scene("paper-fig3-sparse"), 8, max_iterations=2)
    assert not result.converged and "no convergence" in result.diagnostics["message"]
    assert pressure_figure(result) != pressure_figure(solve_fft(load_scene(
        "paper-fig3-sparse"), 8))


# --- seeded fuzz ------------------------------------------------------------------------------
BAD_VALUES = ["-1", "0", "nan", "inf", "-inf", "1e400", "1e-400", "0_3", "0x10", "abc", "",
              "true", "1,5", " ", "9" * 400, "1e308", "5e-324", "+", ".", "1e", "0.5000001",
              "-0", "3.5", "1e16", "1e-3", "0.9069", "2.3e-3", "none"]
KEYS = {"lens": ["radius_mm", "E_Pa", "nu", "rigid"],
        "pillars": ["diameter_um", "height_um", "surface_fraction", "pitch_um", "E_Pa", "nu",
                    "rigid"],
        "substrate": ["E_Pa", "nu", "rigid"], "load": ["indentation_um"],
        "nope": ["x"]}
OPTIONS = {
    "solve": ["--model", "--elements-per-diameter", "--cells-per-diameter", "--mesh-size",
              "--cells", "--contact", "--device"],
    "converge": ["--model", "--levels", "--elements-per-diameter", "--cells-per-diameter",
                 "--mesh-size", "--workers", "--executor"],
    "compare": ["--levels", "--elements-per-diameter", "--mesh-size", "--workers"],
    "gecit": ["--ratios", "--aspect", "--levels", "--mesh-size", "--elements-per-diameter",
              "--edge-window", "--edge-skip", "--edge-nodes"],
    "tradeoff": ["--models", "--levels", "--repeats", "--single-above", "--max-time",
                 "--elements-per-diameter", "--cells-per-diameter", "--mesh-size"],
}
OPTION_VALUES = BAD_VALUES + ["1", "2", "3", "5", "11", "0.5", "bem", "bem-fft", "fem-axisym",
                              "bem,fem-axisym", "covered", "paper", "cpu", "serial", "dask",
                              "--json"]


def _scene_file(rng: random.Random, tmp_path, k: int) -> str:
    """A mutation of a valid scene file: a value replaced, a key dropped or added, a table
    renamed, the text cut short, or bytes that are not text."""
    lines = VALID_SCENE.splitlines()
    kind = rng.choice(["value", "drop", "add", "table", "cut", "bytes", "empty"])
    path = tmp_path / f"fuzz-{k}.toml"
    if kind == "bytes":
        path.write_bytes(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200))))
        return str(path)
    i = rng.randrange(len(lines))
    if kind == "value" and "=" in lines[i]:
        key = lines[i].split("=")[0]
        value = rng.choice(["-1", "0", "nan", "inf", "1e400", '"text"', "true", "[1, 2]",
                            "{a = 1}", "9" * 400, "1e-320", "0.5000001", "1e16", "0.9069",
                            "0x10", "1_000"])
        lines[i] = f"{key}= {value}"
    elif kind == "drop":
        del lines[i]
    elif kind == "add":
        lines.insert(i + 1, rng.choice(["extra = 1", "[extra]", "nu = 0.3", "pitch_um = 20"]))
    elif kind == "table" and lines[i].startswith("["):
        lines[i] = rng.choice(["[lens.inner]", "[[lens]]", "[Lens]", "[]"])
    elif kind == "cut":
        lines = lines[:i]
    elif kind == "empty":
        lines = []
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def _override(rng: random.Random) -> str:
    table = rng.choice(list(KEYS))
    if rng.random() < 0.1:
        return rng.choice([f"{table}=none", f"{table}", "=1", "lens.=1", ".nu=0.3", "lens..nu=1"])
    return f"{table}.{rng.choice(KEYS[table])}={rng.choice(BAD_VALUES)}"


@pytest.fixture
def fake_fft(fakes, monkeypatch):
    """The FFT model and fem-3d faked too: their real solves at the fuzz's resolutions cost
    minutes (a compare on paper-fig3-dense, which picks fem-3d since the lattice FEM
    landed, took 84 of the fuzz's 93 s)."""
    from fakes import register

    module = sys.modules["xval_fakes"]
    module.fake_fft = lambda scene, cells_per_diameter=32: module.fake_bem(
        scene, elements_per_diameter=cells_per_diameter)
    register(monkeypatch, "bem-fft", "xval_fakes:fake_fft", ("cells_per_diameter",))
    register(monkeypatch, "fem-3d", "xval_fakes:fake_fem", ("mesh_size",))
    return fakes


def _stuck(scene, **options):
    from fakes import fake_bem

    result = fake_bem(scene, **options)
    result.converged = False
    result.diagnostics["message"] = "no convergence (fuzz)"
    return result


def test_fuzz_the_cli(fake_fft, tmp_path, cli, monkeypatch):
    """Seeded bad scene files, overrides and options for every command, and models that fail
    in each way a solve can: every outcome is exit 0-3 with its one line, never a traceback
    (fake models: any run that passes the checks costs nothing)."""
    from fakes import fake_bem

    module = sys.modules["xval_fakes"]
    faults = [fake_bem] * 4 + [_stuck, _broken(MemoryError()), _broken(ToolError("simulated"))]
    rng = random.Random(SEED)
    codes = {0: 0, 1: 0, 2: 0, 3: 0}
    for k in range(240):
        monkeypatch.setattr(module, "fake_bem", rng.choice(faults))
        command = rng.choice(["solve", "solve", "converge", "compare", "gecit", "tradeoff"])
        # cheap defaults first: the random options after them win
        argv = [command, *{"gecit": ["--ratios", "1", "--aspect", "0.5", "--levels", "1"],
                           "compare": ["--no-render", "--levels", "2"],
                           "converge": ["--levels", "2"]}.get(command, [])]
        if command != "gecit" or rng.random() < 0.5:
            scene = (_scene_file(rng, tmp_path, k) if rng.random() < 0.4
                     else rng.choice(preset_names()))
            argv += ["--scene", scene]
        for _ in range(rng.randrange(0, 3)):
            argv += ["--set", _override(rng)]
        for _ in range(rng.randrange(0, 3)):
            argv += [rng.choice(OPTIONS[command]), rng.choice(OPTION_VALUES)]
        if command == "tradeoff":
            argv += ["--repeats", "1", "--models", "bem"]
        argv += _common(command, tmp_path / str(k))
        code, _, _ = outcome(cli, *argv)
        codes[code] += 1
    # the seeded inputs reach every kind of outcome that input can cause
    assert codes[2] > 100 and min(codes.values()) > 0, codes


def test_a_slow_plan_says_what_it_does(cli, monkeypatch):
    """`plan --scene paper-fig3-sparse` was silent for 13 s on a cold start: a plan slower
    than PROGRESS_AFTER_S says its step (here: every plan)."""
    import importlib

    monkeypatch.setattr(importlib.import_module("validation.cli.plan"), "PROGRESS_AFTER_S", 0.0)
    code, out, err = cli("plan", "--scene", "paper-fig3-sparse")
    assert code == 0 and "choice" in out
    steps = [ln for ln in err.splitlines() if ln.startswith("[plan] ")]
    assert steps and "reading the planner's error and cost tables" in steps[0], err
