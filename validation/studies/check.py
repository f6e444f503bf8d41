"""``pillar-xval check SPEC.toml``: tolerance checks for CI, without writing Python.

A spec lists checks; each runs a model on a scene and compares it, quantity by quantity,
with a second model or a closed form, within a stated tolerance and its source::

    [[check]]
    name = "dense BEM against fem-axisym, rigid punch"
    scene = "single-pillar"                    # a preset, or a scene file beside the spec
    set = ["pillars.rigid=true", "substrate.rigid=true"]
    model = "bem"
    options = { elements_per_diameter = 11 }
    reference = "fem-axisym"                   # a model, or "hertz" | "punch" | "spring"
    reference_options = { mesh_size = 2.0 }
    quantities = ["F_T"]
    rtol = 0.03
    source = "measured 2.1 % at P = 11"

Every case runs on the study engine (cached in ``--out``/cases, so a rerun solves only what
changed); the comparison is :func:`validation.testing.assert_close`, so a failing row carries
the same message a pytest check would.  Results: a table, ``check.json`` and, on request, a
JUnit XML report (one test case per check) that any CI shows as tests.
"""

from __future__ import annotations

import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from pillar_xval.scenes import InputError, ScopeError, load_scene, preset_names

from ..output.formatting import aligned
from ..testing import (CLOSED_FORMS, QUANTITY_BY_KEY, assert_close,
                       assert_matches_closed_form, check_tolerance, closed_form_refusal,
                       quantity_value)

__all__ = ["CheckSpec", "junit_xml", "load_spec", "report_name", "run_checks", "spec_path",
           "table_text", "xml_safe"]

_CHECK_KEYS = {"name", "scene", "set", "model", "options", "reference", "reference_options",
               "quantities", "rtol", "atol", "source"}


@dataclass(frozen=True)
class CheckSpec:
    """One check of a spec: ``model`` on ``scene`` against ``reference``."""

    name: str
    scene: object
    model: str
    options: dict
    reference: str
    reference_options: dict = field(default_factory=dict)
    quantities: tuple = ("F_T",)
    rtol: float = 0.0
    atol: float = 0.0
    source: str = ""

    @property
    def closed_form(self) -> bool:
        return self.reference in CLOSED_FORMS


def _plain_name(where: str, name: str) -> str:
    """``name`` when it holds no control character (it is printed, and written to JUnit XML,
    which cannot carry most of them); InputError naming the first one otherwise."""
    bad = next((c for c in name if ord(c) < 32 or 127 <= ord(c) < 160), None)
    if bad is not None:
        raise InputError(f"{where} name = {name!r}: holds the control character "
                         f"U+{ord(bad):04X}; a check's name is printed and written to JUnit XML")
    return name


def _applies(where: str, role: str, name: str, scene) -> None:
    """ScopeError (exit 2) where ``name``, as the check's ``role``, does not apply to
    ``scene``: a model out of its declared regimes, or a closed form that is no reference for
    the scene (:func:`validation.testing.closed_form_refusal`)."""
    from ..planner.features import scope_refusal

    refusal = closed_form_refusal(scene, name) if role == "reference" and \
        name in CLOSED_FORMS else scope_refusal(name, scene)
    if refusal is not None:
        raise ScopeError(f"{where} {role} = {name!r}: {refusal}")


def _one(i: int, table, base_dir: Path) -> CheckSpec:
    from ..registry import MODELS, check_options, scene_defaults

    where = f"[[check]] {i + 1}"
    if not isinstance(table, dict):
        raise InputError(f"{where}: must be a table")
    unknown = sorted(set(table) - _CHECK_KEYS)
    if unknown:
        raise InputError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(_CHECK_KEYS)}")
    for key in ("scene", "model", "reference", "rtol"):
        if key not in table:
            raise InputError(f"{where}: {key!r} is missing")
    name = _plain_name(where, str(table.get("name", f"check {i + 1}")))
    where = f"[[check]] {name!r}:"
    scene_name = str(table["scene"])
    if scene_name not in preset_names():
        path = Path(scene_name)
        scene_name = str(path if path.is_absolute() else base_dir / path)
    overrides = table.get("set", [])
    if not isinstance(overrides, list) or not all(isinstance(s, str) for s in overrides):
        raise InputError(f"{where} 'set' must be a list of \"table.key=value\" strings")
    scene = load_scene(scene_name, overrides)
    model, reference = str(table["model"]), str(table["reference"])
    options, ref_options = table.get("options", {}), table.get("reference_options", {})
    check_options(model, options, f"{where} model", scene)
    _applies(where, "model", model, scene)
    if reference not in CLOSED_FORMS and reference not in MODELS:
        raise InputError(f"{where} reference {reference!r}: unknown model; available: "
                         f"{', '.join(sorted(MODELS))} (or a closed form: "
                         f"{', '.join(CLOSED_FORMS)})")
    if reference in CLOSED_FORMS:
        if ref_options:
            raise InputError(f"{where} reference_options: a closed form takes none")
    else:
        check_options(reference, ref_options, f"{where} reference", scene)
    _applies(where, "reference", reference, scene)
    quantities = table.get("quantities", ["F_T"])
    if isinstance(quantities, str):
        quantities = [quantities]
    if not isinstance(quantities, list) or not quantities or \
            any(q not in QUANTITY_BY_KEY for q in quantities):
        raise InputError(f"{where} quantities = {quantities!r}: a list of "
                         f"{', '.join(QUANTITY_BY_KEY)}")
    return CheckSpec(name, scene, model, scene_defaults(model, scene, options), reference,
                     ref_options if reference in CLOSED_FORMS else
                     scene_defaults(reference, scene, ref_options),
                     tuple(quantities), check_tolerance(f"{where} rtol", table["rtol"]),
                     check_tolerance(f"{where} atol", table.get("atol", 0.0)),
                     str(table.get("source", "")))


def spec_path(path) -> Path:
    """The spec file ``path`` names: itself where it exists; a relative path that does not
    exist here but names one of the toolkit's own files (``validation/examples/checks.toml``)
    is that file, wherever the command runs."""
    path = Path(path)
    if path.is_absolute() or path.exists():
        return path
    own = Path(__file__).resolve().parents[2] / path
    return own if own.is_file() else path


def report_name(path) -> str:
    """The name of a spec's report (``out/check/NAME``, the JUnit suite): its stem, when that
    is a plain file name; a spec named ``...toml`` (stem ``..``) would send the report to the
    parent folder, so it is refused (InputError, exit 2)."""
    stem = Path(path).stem
    if stem in ("", ".", "..") or Path(stem).name != stem or "\\" in stem:
        raise InputError(f"check spec {str(path)!r}: its stem {stem!r} cannot name the report "
                         "folder out/check/<stem> (it would leave out/check): rename the spec "
                         "or give --out")
    return stem


def load_spec(path) -> list[CheckSpec]:
    """The checks of a spec file; InputError (exit 2) naming the key for anything wrong."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"check spec {str(path)!r}: cannot read it "
                         f"({exc.strerror or exc})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"check spec {path}: not valid TOML ({exc})") from None
    unknown = sorted(set(data) - {"check"})
    if unknown:
        raise InputError(f"check spec {path}: unknown key(s) {unknown}; the spec is a list "
                         "of [[check]] tables")
    checks = data.get("check", [])
    if not isinstance(checks, list) or not checks:
        raise InputError(f"check spec {path}: give at least one [[check]] table")
    specs = [_one(i, t, path.parent) for i, t in enumerate(checks)]
    names = [s.name for s in specs]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise InputError(f"check spec {path}: check name(s) given twice: {repeated}")
    return specs


def run_checks(specs: list[CheckSpec], cache_dir: Path, engine) -> list[dict]:
    """Run every case of ``specs`` (one engine batch) and compare; one row per check."""
    from ..engine import Case

    cases = []
    for s in specs:
        cases.append(Case(s.model, s.scene, s.options, tag=s.name))
        if not s.closed_form:
            cases.append(Case(s.reference, s.scene, s.reference_options, tag=s.name))
    outcomes = iter(engine.run(cases, cache_dir, label="check"))
    rows = []
    for s in specs:
        got = next(outcomes)
        ref = None if s.closed_form else next(outcomes)
        row = {"name": s.name, "scene": s.scene.name, "model": s.model,
               "reference": s.reference, "quantities": list(s.quantities), "rtol": s.rtol,
               "atol": s.atol, "source": s.source, "passed": False, "message": "",
               "values": {}}
        try:
            result = got.unwrap()
            row["model_label"] = result.label  # with its pillar model
            row["values"] = {q: quantity_value(result, q) for q in s.quantities}
            if s.closed_form:
                assert_matches_closed_form(result, s.reference, rtol=s.rtol,
                                           quantities=s.quantities, source=s.source)
            else:
                expected = ref.unwrap()
                row["reference_label"] = expected.label
                row["references"] = {q: quantity_value(expected, q) for q in s.quantities}
                assert_close(result, expected, s.quantities, rtol=s.rtol, atol=s.atol,
                             source=s.source)
            row["passed"] = True
        except AssertionError as exc:
            row["message"] = str(exc)
        except Exception as exc:  # a case that failed: the check fails, with its reason
            row["message"] = f"the case failed: {' '.join(str(exc).split())}"
        rows.append(row)
    return rows


def table_text(rows: list[dict]) -> str:
    """The checks as a table (models named with their pillar models), then each failure's
    message."""
    header = ("check", "model", "reference", "quantities", "rtol", "result")
    lines = [header] + [(r["name"], r.get("model_label", r["model"]),
                         r.get("reference_label", r["reference"]), ",".join(r["quantities"]),
                         f"{r['rtol']:g}", "pass" if r["passed"] else "FAIL") for r in rows]
    out = aligned(lines)
    for r in rows:
        if not r["passed"]:
            out.append(f"\n{r['name']}:\n{r['message']}")
    return "\n".join(out)


def xml_safe(text) -> str:
    """``text`` with every character XML 1.0 cannot carry (control characters but tab, line
    feed and carriage return; lone surrogates; U+FFFE, U+FFFF) written as ``\\xNN`` /
    ``\\uNNNN``: ElementTree escapes markup but writes these as they are, which makes the
    document ill-formed."""
    def ok(c: str) -> bool:
        o = ord(c)
        return (o in (0x9, 0xA, 0xD) or 0x20 <= o <= 0xD7FF or 0xE000 <= o <= 0xFFFD
                or o >= 0x10000)

    return "".join(c if ok(c) else (f"\\x{ord(c):02x}" if ord(c) < 256 else f"\\u{ord(c):04x}")
                   for c in str(text))


def junit_xml(rows: list[dict], suite: str, seconds: float) -> str:
    """A JUnit XML report: one test case per check, a failure element with its message;
    well-formed whatever the names and messages hold (:func:`xml_safe`)."""
    failures = sum(not r["passed"] for r in rows)
    suite = xml_safe(suite)
    top = ET.Element("testsuites", tests=str(len(rows)), failures=str(failures))
    ts = ET.SubElement(top, "testsuite", name=suite, tests=str(len(rows)),
                       failures=str(failures), errors="0", skipped="0", time=f"{seconds:.3f}")
    for r in rows:
        tc = ET.SubElement(ts, "testcase", classname=xml_safe(f"{suite}.{r['scene']}"),
                           name=xml_safe(r["name"]), time="0")
        if not r["passed"]:
            first = r["message"].splitlines()[0] if r["message"] else "failed"
            ET.SubElement(tc, "failure", message=xml_safe(first),
                          type="ToleranceError").text = xml_safe(r["message"])
    ET.indent(top)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(top, encoding="unicode") \
        + "\n"
