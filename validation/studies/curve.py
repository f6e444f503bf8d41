"""The loading curve: models at a sequence of loads, forces or indentations, on the engine.

Experiments press a lens with a rising normal force and measure the indentation, the contact
radius and the real contact area as it rises.  :func:`curve_study` solves one scene at each
load (its load replaced: ``Scene.at_force`` or ``Scene.at_indentation``) with each model,
as cases on the study engine (cached, resumable, with progress), and reads per model and
load the indentation, force, contact radius, real contact area, centre pressure and pillars
in contact.  With ``levels`` >= 2 each model with a ladder climbs it at every load and each
quantity gets its numerical uncertainty band, the GCI of its levels (a spread where the
levels give no order: :mod:`validation.analysis.verification`), the finest level's value in
the rows.  The Hertz and single-pillar (spring) closed forms over the same loads are the
references a figure draws.

A user's measured points (:func:`read_data`): a CSV file with a header row naming its
columns with their units, ``force_uN`` and any of ``indentation_um``, ``contact_radius_um``
and ``real_contact_area_um2``; lines starting with ``#`` are comments, an empty cell of a
measured column is a point not measured.  Anything else is refused before anything is
solved, in one line naming the file, the line and the column.

Files: ``curve.csv`` (one row per model and load: :data:`CSV_COLUMNS`, SI), ``curve.png``
(F-zeta, a-F, A-F, sigma0-F: :func:`validation.output.plots.plot_curve`) and ``curve.json``
(everything, written last).
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from pathlib import Path

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import InputError, Scene, analytic

from ..analysis.verification import study
from ..engine import Case, Engine
from ..registry import MODELS, ladder_for
from ._ladder import check_ladder

__all__ = ["CSV_COLUMNS", "DATA_COLUMNS", "OUTPUTS", "closed_form_curves", "curve_study",
           "read_data", "write_outputs"]

OUTPUTS = ("curve.csv", "curve.png", "curve.json")
CSV_COLUMNS = ("model", "force_N", "indentation_m", "contact_radius_m", "real_contact_area_m2",
               "centre_pressure_Pa", "pillars_in_contact", "floor_force_N",
               "floor_contact_area_m2", "regime", "converged")
# The quantities of a curve's row: key, ContactResult attribute (SI).
QUANTITIES = (("zeta", "indentation_m"), ("F_T", "total_force_N"), ("a", "contact_radius_m"),
              ("A", "real_contact_area_m2"), ("sigma0", "centre_pressure_Pa"))
# A user's data file: each column, its SI attribute and the factor from its unit to SI.
DATA_COLUMNS = {"force_uN": ("total_force_N", 1e-6), "indentation_um": ("indentation_m", 1e-6),
                "contact_radius_um": ("contact_radius_m", 1e-6),
                "real_contact_area_um2": ("real_contact_area_m2", 1e-12)}
MAX_DATA_BYTES = 1 << 20
MAX_DATA_POINTS = 10_000
# A decimal number as people type it (as ``--set`` reads them: no nan, inf or _).
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
# Closed-form reference curves: points between the smallest and the largest load.
REFERENCE_POINTS = 60


def curve_cases(scenes: list[Scene], models: list[str], *, levels: int = 1,
                coarsest: dict | None = None, options: dict | None = None) -> list[Case]:
    """The cases of the curve: per model, per load, its ``levels`` refinements (one case for
    a model without a ladder or with ``levels`` = 1, at ``coarsest``'s value of its option)."""
    coarsest, options = coarsest or {}, options or {}
    cases = []
    for model in models:
        declared = MODELS[model]
        mine = {k: v for k, v in options.items() if k in declared.options}
        ladder = declared.ladder
        for i, scene in enumerate(scenes):
            tag = f"{model} load {i + 1}/{len(scenes)}"
            if ladder is None or levels == 1:
                given = {ladder.option: coarsest[ladder.option]} if (
                    ladder is not None and ladder.option in coarsest) else {}
                cases.append(Case(model, scene, {**given, **mine}, tag=tag))
                continue
            start = coarsest.get(ladder.option)
            values = check_ladder(model, levels, start)
            cases += [Case(model, scene, {**ladder.options_at(v), **mine},
                           tag=f"{tag} level {k + 1}/{levels}") for k, v in enumerate(values)]
    return cases


def curve_study(scenes: list[Scene], models: list[str], cache_dir: Path, *,
                engine: Engine | None = None, levels: int = 1, coarsest: dict | None = None,
                options: dict | None = None, data: dict | None = None,
                base: Scene | None = None) -> dict:
    """Run (or resume from ``cache_dir``) every model at every load of ``scenes`` (one scene
    per load, in rising order) and read the curve (module docstring); ``base`` is the scene
    they load (its name and parameters label the figure; default the first).

    Returns a JSON-ready dict: ``control`` (force or indentation), ``loads`` (SI), ``rows``
    (per model and load: the quantities, their bands with ``levels`` >= 2, convergence and
    message; a case that failed: its error), ``references`` (:func:`closed_form_curves`),
    ``data`` (the user's points, when given), ``falls`` (per model, where its indentation,
    contact radius or pillar count falls as the load rises: none on a physical curve),
    ``failed`` and ``unconverged`` (counts).
    """
    control = scenes[0].load_control
    cases = curve_cases(scenes, models, levels=levels, coarsest=coarsest, options=options)
    own = engine is None
    engine = engine or Engine("serial", label="curve")
    try:
        outcomes = engine.run(cases, cache_dir, label="curve")
    finally:
        if own:
            engine.close()
    by_case = {}
    for o in outcomes:
        by_case.setdefault((o.case.model, _load_of(o.case.scene)), []).append(o)
    rows, failed, unconverged, monotone = [], [], [], {}
    for model in models:
        mine = [_row(model, scene, by_case[(model, _load_of(scene))]) for scene in scenes]
        rows += mine
        failed += [r for r in mine if "error" in r]
        unconverged += [r for r in mine if "error" not in r and not r["converged"]]
        monotone[model] = _falls(mine)
    return {"scene": (base or scenes[0]).to_dict(), "control": control,
            "loads": [_load_of(s) for s in scenes], "models": list(models), "levels": levels,
            "options": options or {}, "rows": rows, "falls": monotone,
            "references": closed_form_curves(scenes[0], [_load_of(s) for s in scenes],
                                             control),
            "data": data, "failed": len(failed), "unconverged": len(unconverged),
            "transitions": transitions(rows, models)}


def transitions(rows: list[dict], models) -> dict:
    """Per model, where its curve first touches the floor (suspended to mixed): the last
    load without floor contact and the first with it (None where the curve never crosses)."""
    out = {}
    for model in models:
        done = [r for r in rows if r["model"] == model and "error" not in r]
        for before, after in zip(done, done[1:]):
            if before.get("regime") != "mixed" and after.get("regime") == "mixed":
                out[model] = {"suspended_load": before["load"], "mixed_load": after["load"],
                              "suspended_indentation_m": before["indentation_m"],
                              "mixed_indentation_m": after["indentation_m"]}
                break
        else:
            out[model] = None
    return out


def _falls(rows: list[dict]) -> list[str]:
    """Where a model's indentation, contact radius or pillar count falls as the load rises
    (none on a physical curve: a larger load only adds contact), one line each."""
    out = []
    done = [r for r in rows if "error" not in r]
    for key in ("indentation_m", "contact_radius_m", "pillars_in_contact"):
        for before, after in zip(done, done[1:]):
            if after[key] < before[key]:
                out.append(f"{key} falls from {before[key]:.6g} to {after[key]:.6g} between "
                           f"the loads {before['load']:.6g} and {after['load']:.6g}")
    return out


def _load_of(scene: Scene) -> float:
    return scene.force_N if scene.force_N is not None else scene.indentation_m


def _row(model: str, scene: Scene, outcomes: list) -> dict:
    """The curve's row of ``model`` at one load: the finest level, and bands over the levels."""
    row = {"model": model, "load": _load_of(scene)}
    errors = [o for o in outcomes if not o.ok]
    if errors:
        row["error"] = f"{type(errors[0].error).__name__}: {errors[0].error}"
        row["input_error"] = isinstance(errors[0].error, InputError)
        return row
    results = [o.result for o in outcomes]
    finest = results[-1]
    row.update({attr: float(getattr(finest, attr)) for _, attr in QUANTITIES})
    row.update(pillars_in_contact=int(finest.pillars_in_contact),
               floor_force_N=float(finest.floor_force_N),
               floor_contact_area_m2=float(finest.floor_contact_area_m2),
               regime=finest.regime,
               converged=all(r.converged for r in results),
               message="; ".join(str(r.diagnostics.get("message", "")) for r in results
                                 if not r.converged),
               options=dict(outcomes[-1].case.options), cached=all(o.cached for o in outcomes))
    if len(results) >= 2:
        ladder = ladder_for(model)
        h = [ladder.size(o.case.options[ladder.option]) for o in outcomes]
        row["bands"] = {attr: _band(study(h, [getattr(r, attr) for r in results]))
                        for _, attr in QUANTITIES}
    return row


def _band(st: dict) -> float:
    """The uncertainty of a quantity's finest value (SI): its GCI band, or the spread of the
    levels (x3) where they give no order."""
    g = st["gci"]
    return float(g["uncertainty"] if g["status"] == "ok" else g["fallback_uncertainty"])


def closed_form_curves(scene: Scene, loads: list[float], control: str) -> dict:
    """The Hertz and single-pillar (spring model) curves between the smallest and the largest
    load, each point at the indentation where the closed form carries the force (under force
    control) or at the indentation (SI arrays by quantity attribute; spring on pillars only)."""
    lo, hi = min(loads), max(loads)
    grid = ([lo] if lo == hi else
            [lo * (hi / lo) ** (k / (REFERENCE_POINTS - 1)) for k in range(REFERENCE_POINTS)])
    R, gamma = scene.lens.radius_m, scene.half_space_compliance
    out = {}
    if gamma > 0.0:
        zeta = [analytic.Hertz.indentation_for_force(v, R, gamma) if control == "force" else v
                for v in grid]
        hertz = [analytic.Hertz(R, z, gamma) for z in zeta]
        share = 1.0 if scene.pillars is None else scene.pillars.surface_fraction
        out["hertz"] = {"label": "Hertz", "indentation_m": zeta,
                        "total_force_N": [h.force for h in hertz],
                        "contact_radius_m": [h.contact_radius for h in hertz],
                        "real_contact_area_m2": [share * h.contact_area for h in hertz],
                        "centre_pressure_Pa": [h.centre_pressure for h in hertz]}
    if scene.pillars is not None and analytic.effective_compliance(scene) > 0.0:
        d, gamma_star = scene.pillars.diameter_m, analytic.effective_compliance(scene)
        zeta = [v * gamma_star / d if control == "force" else v for v in grid]
        punch = [analytic.FlatPunch(d, z, gamma_star) for z in zeta]
        out["spring"] = {"label": "one pillar (spring model)", "indentation_m": zeta,
                         "total_force_N": [p.force for p in punch],
                         "contact_radius_m": [d / 2.0] * len(grid),
                         "real_contact_area_m2": [math.pi * d * d / 4.0] * len(grid),
                         "centre_pressure_Pa": [p.centre_pressure for p in punch]}
    return out


def read_data(path) -> dict:
    """A user's measured points (module docstring), SI: ``{"file", "columns", "points"}``
    with one dict per point of the SI attributes it gives.  InputError, in one line naming
    the file, the line and the column, for anything malformed."""
    path = Path(path)
    shown = str(path) if str(path).isprintable() else repr(str(path))
    try:
        if not path.is_file():
            raise InputError(f"--data {shown}: not a file")
        if path.stat().st_size > MAX_DATA_BYTES:
            raise InputError(f"--data {shown}: larger than {MAX_DATA_BYTES} bytes (a table of "
                             "measured points is far smaller)")
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"--data {shown}: cannot read the file ({exc.strerror})") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"--data {shown}: byte {exc.start} is not UTF-8 text (a CSV file is "
                         "text)") from None
    lines = [(n, line) for n, line in enumerate(text.splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"--data {shown}: no header row (expected a row naming the columns: "
                         f"force_uN and any of {', '.join(list(DATA_COLUMNS)[1:])})")
    (n0, header_line), body = lines[0], lines[1:]
    header = [c.strip() for c in next(csv.reader([header_line]))]
    for k, name in enumerate(header):
        if name not in DATA_COLUMNS:
            raise InputError(f"--data {shown}: line {n0}, column {k + 1} {name!r}: unknown; "
                             f"the columns are {', '.join(DATA_COLUMNS)} (units in the names)")
        if name in header[:k]:
            raise InputError(f"--data {shown}: line {n0}, column {k + 1} {name!r}: given twice")
    if "force_uN" not in header:
        raise InputError(f"--data {shown}: line {n0}: no force_uN column (every point needs "
                         "its force, micronewtons)")
    if not body:
        raise InputError(f"--data {shown}: no data rows after the header (line {n0})")
    if len(body) > MAX_DATA_POINTS:
        raise InputError(f"--data {shown}: {len(body)} rows, more than {MAX_DATA_POINTS}")
    points = []
    for n, line in body:
        cells = [c.strip() for c in next(csv.reader([line]))]
        if len(cells) != len(header):
            raise InputError(f"--data {shown}: line {n}: {len(cells)} cells, the header names "
                             f"{len(header)} columns")
        point = {}
        for name, cell in zip(header, cells):
            if cell == "" and name != "force_uN":
                continue  # not measured at this point
            if not _NUMBER.fullmatch(cell):
                raise InputError(f"--data {shown}: line {n}, column {name}: {cell[:40]!r} is "
                                 "not a decimal number")
            value = float(cell)
            positive = name in ("force_uN", "indentation_um")  # a contact may be none yet
            if not math.isfinite(value) or value < 0.0 or (positive and value == 0.0):
                raise InputError(f"--data {shown}: line {n}, column {name}: {cell} is out of "
                                 f"range ({'> 0' if positive else '>= 0'})")
            attr, factor = DATA_COLUMNS[name]
            point[attr] = value * factor
        points.append(point)
    return {"file": str(path), "columns": header, "points": points}


def write_outputs(doc: dict, out: Path) -> list[str]:
    """``curve.csv``, ``curve.png`` and, last, ``curve.json`` in ``out``; their names."""
    from ..output.plots import plot_curve

    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(CSV_COLUMNS)
    for r in doc["rows"]:
        if "error" in r:
            continue
        w.writerow([r["model"], repr(r["total_force_N"]), repr(r["indentation_m"]),
                    repr(r["contact_radius_m"]), repr(r["real_contact_area_m2"]),
                    repr(r["centre_pressure_Pa"]), r["pillars_in_contact"],
                    repr(r.get("floor_force_N", 0.0)), repr(r.get("floor_contact_area_m2", 0.0)),
                    r.get("regime", ""), r["converged"]])
    write_atomic(Path(out) / "curve.csv", buf.getvalue())
    plot_curve(doc, Path(out) / "curve.png")
    write_atomic(Path(out) / "curve.json", json.dumps(doc, indent=2, allow_nan=False))
    return list(OUTPUTS)

