"""Sphinx glue of pillar-xval's documentation.

- Docstrings write absolute values and norms as ``|x|``, plain text that reads well in a
  terminal's ``help()``; reStructuredText would take ``|x|`` for a substitution.  They are
  escaped when autodoc reads them (outside literal text and tables), so the source keeps its
  plain notation.
- autodoc documents only the project's own objects (not, e.g., scipy's ``cKDTree`` imported
  into a module), and skips a package's re-export that shares its name with a submodule
  (``validation.planner.plan``, the function and the module), which it would describe twice.
- The scene-file keys, the presets, the result schema and the kept benchmark records are
  tables generated from the code and its data
  (``docs/_tables/*.md``, included by their pages), so a new key or field appears without
  editing the docs; a result field without a description fails the build.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import re
from pathlib import Path

from sphinx.util import logging

LOG = logging.getLogger(__name__)
PROJECT_PACKAGES = ("pillar_xval", "bem_solver", "fem_reference", "meshes", "validation")

# |x| where docutils would see a substitution reference: a bar, no space, text, no space, a
# bar, not inside ``literal`` text.
_BARS = re.compile(r"(?<![\\|\w])\|(?=\S)([^|`]*?\S)\|(?![|\w])")
_LITERAL = re.compile(r"``.*?``")
# |x spanning a line break: an opening bar left at the end of one line, its closing bar on
# the next.
_OPEN_AT_END = re.compile(r"(?<![\\|\w])\|(?=\S)([^|`]*)$")
_CLOSE_AT_START = re.compile(r"^([^|`]*\S)\|(?![|\w])")


def escape_bars(line: str) -> str:
    """Escape ``|x|`` in one docstring line, leaving ````literal```` spans alone."""
    out, start = [], 0
    for m in _LITERAL.finditer(line):
        out.append(_BARS.sub(r"\\|\1\\|", line[start:m.start()]))
        out.append(m.group(0))
        start = m.end()
    out.append(_BARS.sub(r"\\|\1\\|", line[start:]))
    return "".join(out)


def _process_docstring(app, what, name, obj, options, lines):
    literal_indent = None
    for i, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if literal_indent is not None:
            if not stripped or indent > literal_indent:
                continue
            literal_indent = None
        if stripped in ("|", "") or stripped.startswith(("| ", "+-", "+=", "==", ">>>")):
            pass  # a table, a line block or a doctest: left as written
        else:
            lines[i] = escape_bars(line)
            nxt = lines[i + 1] if i + 1 < len(lines) else ""
            if _OPEN_AT_END.search(lines[i]) and _CLOSE_AT_START.search(nxt):
                lines[i] = _OPEN_AT_END.sub(r"\\|\1", lines[i])
                lines[i + 1] = _CLOSE_AT_START.sub(r"\1\\|", nxt)
        if stripped.endswith("::") and not stripped.startswith(".."):
            literal_indent = indent
    if what == "module":
        app.env.temp_data["pillar_docs_module"] = name


def _skip_member(app, what, name, obj, skip, options):
    module = getattr(obj, "__module__", None)
    if isinstance(module, str) and not module.startswith(PROJECT_PACKAGES):
        return True
    current = app.env.temp_data.get("pillar_docs_module")
    if current and what == "module" and callable(obj) and module == f"{current}.{name}":
        return True  # documented in its own module's page
    return None


# The result schema: one line per field of ContactResult and PillarForce.
RESULT_FIELDS = {
    "model": "the model's registry name (`bem`, `bem-fft`, `fem-3d`, ...)",
    "scene": "the scene as parsed, in SI (m, Pa)",
    "discretisation": "the model's resolution and options (elements per diameter, mesh size, "
                      "unknowns, ...)",
    "total_force_N": "F_T, the total normal force on the lens (N)",
    "centre_pressure_Pa": "sigma_0, the contact pressure at r = 0 (Pa)",
    "contact_radius_m": "a, the radius of the outermost point of contact (m)",
    "real_contact_area_m2": "A, the area where the pressure is positive (m^2)",
    "pillars_in_contact": "how many pillars carry load",
    "pillar_forces": "per pillar in contact: lattice indices `n, m`, centre `x_m, y_m` (m), "
                     "`force_N` (N)",
    "converged": "whether the solver reached its tolerance (a result that did not is still "
                 "written, and the command exits 1)",
    "iterations": "the solver's iterations (0 for a closed form)",
    "wall_time_s": "the solve's wall time (s)",
    "pillar_top_profile": "the pressure across the central pillar's top: `r_m` from its "
                          "centre (m), `pressure_Pa` (Pa)",
    "diagnostics": "model-specific numbers: residuals, complementarity errors, the planner's "
                   "plan, `message` when not converged",
    "load_control": "`indentation` or `force`: which load the scene gave",
    "indentation_m": "zeta, the indentation (m): the one given, or the one solved under a "
                     "given force",
    "floor_force_N": "the force the floor between the pillars carries (N; 0 while the lens is "
                     "suspended on the pillar tops)",
    "floor_contact_area_m2": "the floor's area in contact (m^2)",
    "floor_contact_radius_m": "the outer radius of the floor's contact (m; 0 when none)",
    "regime": "`flat`, `single-pillar`, `multi-pillar` or `mixed` (pillar tops and floor)",
    "version": "the toolkit's version that computed it",
    "schema_version": "the version of this schema",
    "fields": "arrays for plots and CSV files; not written to `result.json`",
    "n": "lattice index along the first lattice vector",
    "m": "lattice index along the second lattice vector",
    "x_m": "the pillar's centre, x (m)",
    "y_m": "the pillar's centre, y (m)",
    "force_N": "the pillar's normal force (N)",
}


def _type_name(tp) -> str:
    return tp if isinstance(tp, str) else getattr(tp, "__name__", str(tp))


def result_schema_md() -> str:
    """The result schema's fields as Markdown tables, from the dataclasses themselves."""
    from pillar_xval.outcome import ContactResult, PillarForce
    from pillar_xval.outcome._schema import SCHEMA_VERSION

    out = [f"Schema version {SCHEMA_VERSION}.", ""]
    for cls in (ContactResult, PillarForce):
        out += [f"**`{cls.__name__}`**", "", "| field | type | meaning |", "| --- | --- | --- |"]
        for f in dataclasses.fields(cls):
            text = RESULT_FIELDS.get(f.name)
            if text is None:
                LOG.warning("result field %s.%s has no description in docs/_ext/pillar_docs.py "
                            "(RESULT_FIELDS)", cls.__name__, f.name)
                text = ""
            out.append(f"| `{f.name}` | `{_type_name(f.type)}` | {text} |")
        out.append("")
    return "\n".join(out)


def _key_kind(table: str, key: str) -> tuple[str, str]:
    """A scene key's unit and allowed range, from its name and the scene checks' constants."""
    from pillar_xval.scenes import (LENGTH_RANGE_M, MODULUS_RANGE_PA, PHI_CLOSE_PACKING,
                                    POISSON_RANGE)

    def span(lo, hi, unit, scale=1.0):
        return f"[{lo * scale:g}, {hi * scale:g}] {unit}"

    if key.endswith("_um"):
        return "µm", span(*LENGTH_RANGE_M, "m")
    if key.endswith("_mm"):
        return "mm", span(*LENGTH_RANGE_M, "m")
    if key.endswith("_uN"):
        return "µN", "positive"
    if key == "E_Pa":
        return "Pa", span(*MODULUS_RANGE_PA, "Pa") + " (stiffer: `rigid = true`)"
    if key == "nu":
        return "-", span(*POISSON_RANGE, "")
    if key == "surface_fraction":
        return "-", f"(0, {PHI_CLOSE_PACKING:.4f}] (close packing)"
    if key == "rigid":
        return "-", "true or false"
    return "-", ""


SCENE_KEY_NOTES = {
    "lens.radius_mm": "the lens's radius of curvature R",
    "pillars.diameter_um": "the pillar's diameter d",
    "pillars.height_um": "the pillar's height h",
    "pillars.surface_fraction": "Phi, the share of the substrate's area under pillar tops; "
                                "exactly one of this and `pitch_um`",
    "pillars.pitch_um": "the lattice's pitch (centre to centre); exactly one of this and "
                        "`surface_fraction`",
    "load.indentation_um": "zeta, how far the lens's apex is pressed below the pillar tops",
    "lens.E_Pa": "Young's modulus", "pillars.E_Pa": "Young's modulus",
    "substrate.E_Pa": "Young's modulus (missing: the pillars')",
    "lens.nu": "Poisson's ratio", "pillars.nu": "Poisson's ratio",
    "substrate.nu": "Poisson's ratio (missing: the pillars')",
    "lens.rigid": "a rigid body instead of `E_Pa`", "pillars.rigid": "rigid pillars",
    "substrate.rigid": "a rigid substrate",
}


def scene_keys_md() -> str:
    """Every key a scene file may hold, from the parser's own table of keys."""
    from pillar_xval.scenes._tables import KEYS, TOP_KEYS

    out = ["| key | unit | allowed | meaning |", "| --- | --- | --- | --- |"]
    for key in TOP_KEYS:
        out.append(f"| `{key}` | - | one line of text | |")
    for table, keys in KEYS.items():
        for key in keys:
            unit, allowed = _key_kind(table, key)
            note = SCENE_KEY_NOTES.get(f"{table}.{key}", "")
            out.append(f"| `[{table}] {key}` | {unit} | {allowed} | {note} |")
    return "\n".join(out) + "\n"


def presets_md() -> str:
    """The presets as their TOML files give them."""
    from pillar_xval.scenes import preset_names

    root = Path(importlib.util.find_spec("pillar_xval.scenes").origin).parent / "presets"
    out = []
    for name in preset_names():
        text = (root / f"{name}.toml").read_text(encoding="utf-8").rstrip()
        out += [f"### `{name}`", "", "```toml", text, "```", ""]
    return "\n".join(out)


def bench_records_md() -> str:
    """Each kept benchmark record: its command's settings and its table."""
    import json

    folder = Path(importlib.util.find_spec("validation.bench").origin).parent / "measured"
    out = []
    for path in sorted(folder.glob("*.json")):
        record = json.loads(path.read_text(encoding="utf-8"))
        meta = record.get("meta", {})
        settings = ", ".join(f"{k} = {v}" for k, v in meta.items() if not isinstance(v, dict))
        table = record.get("table", "")
        out += [f"### `{path.name}`", "", settings, "", "```", str(table).rstrip(), "```", ""]
    return "\n".join(out)


def _write_generated(app):
    folder = Path(app.srcdir) / "_tables"
    folder.mkdir(exist_ok=True)
    for name, make in (("result_schema.md", result_schema_md), ("scene_keys.md", scene_keys_md),
                       ("presets.md", presets_md),
                       ("bench_records.md", bench_records_md)):
        path = folder / name
        text = make()
        if not path.exists() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")


def setup(app):
    app.connect("builder-inited", _write_generated)
    app.connect("autodoc-process-docstring", _process_docstring)
    app.connect("autodoc-skip-member", _skip_member)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
