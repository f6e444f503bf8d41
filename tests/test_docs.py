"""The documentation site builds with warnings as errors, its tutorials' code runs (each
figure is drawn by its code during the build), and the docs' own glue does what it says."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_ext"))

import pillar_docs  # noqa: E402  (the docs' own extension, not an installed package)

pytestmark = pytest.mark.skipif(shutil.which("sphinx-build", path=str(Path(sys.executable)
                                                                      .parent)) is None,
                                reason="sphinx is not installed (pip install -e '.[docs]')")


def test_site_builds_without_warnings(tmp_path):
    # -W: any warning (a broken reference, a docstring docutils cannot parse, an example
    # that raises) fails the build; --keep-going lists them all.
    out = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b",
                          "html", "-d", str(tmp_path / "doctrees"), str(DOCS),
                          str(tmp_path / "html")],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-6000:]
    html = tmp_path / "html"
    for page in ("index", "getting-started", "cli", "api", "scene-files", "results",
                 "physics", "architecture", "planner", "performance", "models"):
        assert (html / f"{page}.html").is_file(), page
    tutorials = sorted(p.stem for p in (DOCS / "tutorials").glob("*.md"))
    figures = {p.name for p in (html / "_images").glob("*.png")}
    drawn = [t for t in tutorials if f"{t}-1.png" in figures]
    # Every tutorial with a plot directive drew its figure.
    with_plots = [t for t in tutorials
                  if ".. plot::" in (DOCS / "tutorials" / f"{t}.md").read_text()]
    assert with_plots and drawn == with_plots
    # The CLI reference comes from the parser: every subcommand has its section.
    from validation.cli import build_parser

    cli = (html / "cli.html").read_text()
    commands = build_parser()._subparsers._group_actions[0].choices
    missing = [c for c in commands if f'id="pillar-xval-{c}"' not in cli]
    assert not missing, missing


def test_bars_escaped_outside_literals():
    assert pillar_docs.escape_bars("|a - b| <= tol |b|") == r"\|a - b\| <= tol \|b\|"
    assert pillar_docs.escape_bars("``|x|`` and |y|") == r"``|x|`` and \|y\|"
    assert pillar_docs.escape_bars("a | b, c || d") == "a | b, c || d"


def test_bars_escaped_across_a_line_and_not_in_literal_blocks():
    lines = ["misfit (|predicted -", "measured| for model tables)", "Example::", "",
             "    |x| stays", "back |y|"]
    app = SimpleNamespace(env=SimpleNamespace(temp_data={}))
    pillar_docs._process_docstring(app, "function", "f", None, None, lines)
    assert lines == [r"misfit (\|predicted -", r"measured\| for model tables)", "Example::",
                     "", "    |x| stays", r"back \|y\|"]


def test_result_schema_lists_every_field():
    import dataclasses

    from pillar_xval.outcome import ContactResult

    table = pillar_docs.result_schema_md()
    for f in dataclasses.fields(ContactResult):
        assert f"| `{f.name}` |" in table
        assert f.name in pillar_docs.RESULT_FIELDS, f"describe {f.name} in RESULT_FIELDS"


def test_scene_keys_table_follows_the_parser():
    from pillar_xval.scenes._tables import KEYS

    table = pillar_docs.scene_keys_md()
    for section, keys in KEYS.items():
        for key in keys:
            assert f"`[{section}] {key}`" in table


def test_readme_front_page_is_short_and_its_example_runs(capsys):
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 150
    blocks = text.split("```python\n")[1:]
    assert len(blocks) == 1
    exec(compile(blocks[0].split("```")[0], "README.md", "exec"), {})
    forces = capsys.readouterr().out.split()[:3]
    assert len(forces) == 3 and all(float(f) > 0 for f in forces)
