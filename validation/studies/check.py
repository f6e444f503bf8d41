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

from pillar_xval.scenes import InputError, load_scene, preset_names

from ..testing import (CLOSED_FORMS, QUANTITY_BY_KEY, assert_close,
                       assert_matches_closed_form, check_tolerance, quantity_value)

__all__ = ["CheckSpec", "junit_xml", "load_spec", "run_checks", "table_text"]

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


def _check_model(where: str, name, options) -> None:
    from ..registry import MODELS, check_option, model_names

    if name not in MODELS:
        raise InputError(f"{where} = {name!r}: unknown model; available: "
                         f"{', '.join(model_names())}" + (" (or a closed form: "
                                                          f"{', '.join(CLOSED_FORMS)})"
                                                          if "reference" in where else ""))
    if not isinstance(options, dict):
        raise InputError(f"{where}'s options must be a table, not {options!r}")
    accepted = set(MODELS[name].options)
    for key, value in options.items():
        if key not in accepted:
            raise InputError(f"{where} {name}: unknown option {key!r}; it takes "
                             f"{', '.join(sorted(accepted)) or 'none'}")
        check_option(key, value, where=f"{where} {name}: {key} =")


def _one(i: int, table, base_dir: Path) -> CheckSpec:
    where = f"[[check]] {i + 1}"
    if not isinstance(table, dict):
        raise InputError(f"{where}: must be a table")
    unknown = sorted(set(table) - _CHECK_KEYS)
    if unknown:
        raise InputError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(_CHECK_KEYS)}")
    for key in ("scene", "model", "reference", "rtol"):
        if key not in table:
            raise InputError(f"{where}: {key!r} is missing")
    name = str(table.get("name", f"check {i + 1}"))
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
    _check_model(f"{where} model", model, options)
    if reference in CLOSED_FORMS:
        if ref_options:
            raise InputError(f"{where} reference_options: a closed form takes none")
    else:
        _check_model(f"{where} reference", reference, ref_options)
    quantities = table.get("quantities", ["F_T"])
    if isinstance(quantities, str):
        quantities = [quantities]
    if not isinstance(quantities, list) or not quantities or \
            any(q not in QUANTITY_BY_KEY for q in quantities):
        raise InputError(f"{where} quantities = {quantities!r}: a list of "
                         f"{', '.join(QUANTITY_BY_KEY)}")
    return CheckSpec(name, scene, model, dict(options), reference, dict(ref_options),
                     tuple(quantities), check_tolerance(f"{where} rtol", table["rtol"]),
                     check_tolerance(f"{where} atol", table.get("atol", 0.0)),
                     str(table.get("source", "")))


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
            row["values"] = {q: quantity_value(result, q) for q in s.quantities}
            if s.closed_form:
                assert_matches_closed_form(result, s.reference, rtol=s.rtol,
                                           quantities=s.quantities, source=s.source)
            else:
                expected = ref.unwrap()
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
    header = ("check", "model", "reference", "quantities", "rtol", "result")
    lines = [header] + [(r["name"], r["model"], r["reference"], ",".join(r["quantities"]),
                         f"{r['rtol']:g}", "pass" if r["passed"] else "FAIL") for r in rows]
    widths = [max(len(str(line[i])) for line in lines) for i in range(len(header))]
    out = ["  ".join(str(v).ljust(w) for v, w in zip(line, widths)).rstrip()
           for line in lines]
    for r in rows:
        if not r["passed"]:
            out.append(f"\n{r['name']}:\n{r['message']}")
    return "\n".join(out)


def junit_xml(rows: list[dict], suite: str, seconds: float) -> str:
    """A JUnit XML report: one test case per check, a failure element with its message."""
    failures = sum(not r["passed"] for r in rows)
    top = ET.Element("testsuites", tests=str(len(rows)), failures=str(failures))
    ts = ET.SubElement(top, "testsuite", name=suite, tests=str(len(rows)),
                       failures=str(failures), errors="0", skipped="0", time=f"{seconds:.3f}")
    for r in rows:
        tc = ET.SubElement(ts, "testcase", classname=f"{suite}.{r['scene']}", name=r["name"],
                           time="0")
        if not r["passed"]:
            first = r["message"].splitlines()[0] if r["message"] else "failed"
            ET.SubElement(tc, "failure", message=first, type="ToleranceError").text = \
                r["message"]
    ET.indent(top)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(top, encoding="unicode") \
        + "\n"
