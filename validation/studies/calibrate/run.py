"""``pillar-xval calibrate``: measure the planner's error and cost models.

Every number comes from studies run on the engine (resumable, cached in ``OUT/cases``):

- convergence ladders (the rungs of each candidate model's ladder, :mod:`validation.registry`)
  of the dense and FFT BEM on a seeded Latin-hypercube sample of the paper's scenes (and a
  stiff-substrate one),
  fem-axisym's ladder where one pillar touches, all three on flat scenes.  The discretisation
  error of a rung is measured against a converged reference of the same physics: the Hooke
  pillar's is ``tradeoff``'s cross-checked Richardson estimate from both BEMs
  (:func:`validation.studies._ladder.reference_values`), the elastic pillar's the FEM's
  Richardson estimate over mesh_size 2, 1, 0.5;
- the Gecit-like study (:func:`validation.studies.gecit.gecit_study`) on a full grid of
  E_p/E_l x E_s/E_l x h/d x zeta (:data:`.scenes.GECIT_ZETAS_UM`): the Hooke pillar's error
  against the elastic pillar;
- single pillars over zeta and E_p/E_l: the spring model's flat punch against the curved lens
  (the dense BEM's Richardson estimate);
- the lattice sample again: the Hertz-like closed form against the lattice;
- fem-axisym on blocks 1e3, 1e4 and 1e5 pillar radii wide: the truncation of the half-spaces;
- given a report of ``pillar-xval lattice`` (``lattice=``): the Hooke pillar's error in a
  lattice, the Hooke BEM against fem-3d's elastic pillars (:func:`lattice_hooke_table`),
  in place of the Gecit grid's single-pillar values for multi-pillar scenes.

Each case's wall time and peak memory feed one cost fit per model.  The result is two data
files in the format of :mod:`validation.planner.tables` and a report of everything measured.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from pillar_xval.outcome import write_atomic
from pillar_xval.outcome import package_version

from ...engine import Case, Engine, code_version
from ...registry import MODELS, candidates, quantity_values
from ...analysis.verification import gci_three
from .scenes import GECIT_ZETAS_UM, flat_scenes, gecit_scenes, lattice_scenes, punch_scenes
from ...planner.features import features, regime
from ...planner.tables import DATA_FORMAT, DEFAULT_POLICY, ErrorTable
from .._ladder import reference_values
from .costs import _cost_fits, _cost_samples
from .hand import keep_hand_entries
from .lattice_tables import with_lattice
from .measured import HOOKE_MODELS, QKEYS, _measured

__all__ = ["CALIBRATION_SEED", "CANDIDATES", "calibrate", "write_data", "write_document"]

CALIBRATION_SEED = 20240901
# The planner adds each table's local leave-one-out misfit, times this scale.
POLICY = dict(DEFAULT_POLICY)
# Features of the discretisation tables, per regime.
DISC_FEATURES = {"flat": ["log_zeta_r"], "single": ["w", "log_sag"],
                 "multi": ["w", "log_phi_s", "phi"]}
# Dense BEM rungs that give the Hooke reference where one pillar touches (the Gecit-like
# study's, factor 2: 11/15/21 alone were pre-asymptotic there, observed order ~1.7).
SINGLE_REFERENCE_RUNGS = (23, 47, 95)
# fem-axisym on blocks of these sizes (pillar or Hertz radii) measures the truncation.
TRUNCATION_BLOCKS = (1e3, 1e4, 1e5)


# Every candidate of the planner (each rung of each candidate model's ladder, the closed
# forms), with the regimes of its declaration.
CANDIDATES = candidates()


def _cases_of(entry: dict) -> list:
    """The cases one calibration scene needs, by its regime."""
    reg = regime(entry["scene"])["name"]
    models = [m for m in MODELS.values() if m.candidate and reg in m.scopes]
    cases = [Case(m.name, entry["scene"], m.ladder.options_at(v),
                  tag=f"{entry['name']} {m.name}")
             for m in models if m.ladder is not None for v in m.ladder.rungs]
    if reg in ("flat", "single"):
        # One pillar is cheap: the Hooke reference gets the dense BEM refined further.
        cases += [Case("bem", entry["scene"], MODELS["bem"].ladder.options_at(v),
                       tag=f"{entry['name']} bem ref") for v in SINGLE_REFERENCE_RUNGS]
    cases += [Case(m.name, entry["scene"], {}, tag=f"{entry['name']} {m.name}")
              for m in models if m.ladder is None]
    return cases


def _row(outcome) -> dict | None:
    """A plain record of one finished case (None when it failed or was refused)."""
    if not outcome.ok:
        return None
    case, result = outcome.case, outcome.result
    ladder = MODELS[case.model].ladder
    value = case.options.get(ladder.option) if ladder else None
    return {"model": case.model, "value": value, "h": ladder.size(value) if ladder else None,
            "converged": bool(result.converged), "wall_time_s": outcome.timing["wall_time_s"],
            "peak_memory_MB": outcome.timing.get("peak_memory_MB"),
            "pillars": result.pillars_in_contact, **quantity_values(result)}


def _relative(f, ref) -> float | None:
    return None if ref in (None, 0.0) or f is None else (f - ref) / abs(ref)


def _references(reg: str, rows: list) -> dict:
    """Per physics, per quantity: reference value (or None where no converged one exists)."""
    def ladder_rows(models):
        return [r for r in rows if r["model"] in models and r["converged"]
                and r["h"] is not None]

    out = {}
    # The BEMs' physics: Hooke pillars on half-spaces (flat: the half-spaces alone, which
    # the FEM shares).
    half_space = ["bem", "bem-fft"] + (["fem-axisym"] if reg == "flat" else [])
    refs = reference_values(ladder_rows(half_space))
    out["half_space"] = {q: (refs[q]["value"] if refs[q]["band"] is not None else None)
                         for q in QKEYS}
    out["detail"] = {q: {k: refs[q][k] for k in ("value", "band", "model", "basis", "flags")}
                     for q in QKEYS}
    if reg == "single":
        fem = sorted(ladder_rows(["fem-axisym"]), key=lambda r: r["h"])
        fem = [r for r in fem if r["value"] in (0.5, 1.0, 2.0)]
        out["elastic"] = {}
        for q in QKEYS:
            if len(fem) == 3:
                g = gci_three([r["h"] for r in fem], [r[q] for r in fem])
                out["elastic"][q] = g.f_exact if g.status == "ok" else (
                    fem[0][q] if g.status == "round-off" else None)
            else:
                out["elastic"][q] = None
    return out


def _scene_record(entry: dict, outcomes: list) -> dict:
    scene = entry["scene"]
    reg = regime(scene)
    rows = [r for r in (_row(o) for o in outcomes) if r is not None]
    refs = _references(reg["name"], rows)
    for r in rows:
        physics = "elastic" if (r["model"] == "fem-axisym" and reg["name"] == "single") \
            else "half_space"
        r["errors"] = {q: _relative(r[q], refs[physics][q]) for q in QKEYS}
    refused = {f"{o.case.model} {o.case.options}": str(o.error) for o in outcomes if not o.ok}
    return {"name": entry["name"], "family": entry.get("family"), "sets": entry.get("sets"),
            "regime": reg["name"], "features": features(scene, reg), "rows": rows,
            "references": {k: v for k, v in refs.items() if k != "detail"},
            "reference_detail": refs["detail"], "refused": refused}




def _disc_tables(records: list) -> list:
    tables = []
    for cand in CANDIDATES:
        if cand["closed_form"]:
            continue
        model = cand["model"]
        option = MODELS[model].ladder.option
        value = cand["options"][option]
        for reg in MODELS[model].scopes:
            feats = DISC_FEATURES[reg]
            points, errors = [], {q: [] for q in QKEYS}
            for rec in records:
                row = next((r for r in rec["rows"] if r["model"] == model
                            and r["value"] == value and r["converged"]), None)
                if rec["regime"] != reg or row is None:
                    continue
                points.append([rec["features"][f] for f in feats])
                for q in QKEYS:
                    errors[q].append(row["errors"][q])
            if points:
                tables.append(_measured(
                    "discretisation", [model], [reg], feats, points, errors,
                    option={option: value}, source="calibrate: convergence ladders",
                    note=f"(f - f_ref) / |f_ref| of {cand['label']} against the converged "
                         f"reference of its physics, {len(points)} {reg} scenes"))
    return tables


def _closed_form_tables(records: list) -> list:
    """Hertz against the lattice (multi), Hertz against the half-space answer (flat)."""
    tables = []
    for reg, feats, comp, what in (
            ("multi", DISC_FEATURES["multi"], "continuum",
             "the Hertz-like limit against the Hooke lattice (cross-checked BEMs)"),
            ("flat", ["log_zeta_r"], "sphere",
             "Hertz (paraboloid) against the sphere on half-spaces (BEMs and FEM)")):
        points, errors = [], {q: [] for q in QKEYS}
        for rec in records:
            row = next((r for r in rec["rows"] if r["model"] == "hertz"), None)
            if rec["regime"] != reg or row is None:
                continue
            points.append([rec["features"][f] for f in feats])
            for q in QKEYS:
                errors[q].append(row["errors"][q])
        if points:
            tables.append(_measured("model", ["hertz"], [reg], feats, points, errors,
                                    component=comp, source="calibrate: lattice sample",
                                    note=what))
    return tables


def _gecit_table(rows: list, scenes: list) -> ErrorTable:
    """The Hooke pillar's error on one pillar, over the Gecit grid's stiffnesses and aspect
    ratios, and over the lens sag when the grid spans several indentations."""
    names = ["c_p", "c_s", "aspect"]
    if len({e["scene"].indentation_m for e in scenes}) > 1:
        names.append("log_sag")
    points, errors = [], {"F_T": [], "sigma0": []}
    for row, entry in zip(rows, scenes):
        if row.get("status") != "ok":
            continue
        x = features(entry["scene"])
        points.append([x[n] for n in names])
        errors["F_T"].append(row["err_F_T"])
        errors["sigma0"].append(row["err_sigma0"])
    return _measured(
        "model", HOOKE_MODELS, ["single", "multi"],
        names, points, errors, component="hooke",
        source="gecit: Hooke-spring BEM (Richardson) against the elastic-pillar FEM",
        note="measured on one pillar; applied to every pillar of a lattice until a lattice "
             "study (fem-3d) measures it there")






def _punch_table(records: list) -> ErrorTable:
    points, errors = [], {q: [] for q in QKEYS}
    for rec in records:
        row = next((r for r in rec["rows"] if r["model"] == "spring"), None)
        if rec["regime"] != "single" or row is None:
            continue
        points.append([rec["features"]["w"], rec["features"]["log_sag"]])
        for q in QKEYS:
            errors[q].append(row["errors"][q])
    return _measured("model", ["spring"], ["single"], ["w", "log_sag"], points, errors,
                     component="flat-punch", source="calibrate: single pillars over zeta",
                     note="the spring model's flat punch against the Hooke BEM with the "
                          "lens's curvature (dense BEM Richardson, P = 23, 47, 95)")


def _truncation_tables(records: list) -> list:
    tables = []
    for rec in records:
        errors = rec["errors"]
        tables.append(_measured(
            "model", ["fem-axisym"], [rec["regime"]], [], [[]],
            {q: [errors.get(q)] for q in QKEYS}, component="truncation",
            source="calibrate: fem-axisym on blocks 1e3, 1e4, 1e5 radii",
            note=f"f(L) = f_inf + k / L fitted on {rec['scene']}; error of the default block"))
    return tables


def _truncation(cache: Path, scene_names=("single-pillar", "hertz")) -> list:
    """fem-axisym on growing blocks: the relative error of the default block, from a fit
    f(L) = f_inf + k / L over the three widest (mesh_size 1).  Kept in ``cache`` for the
    code version that computed it (the block size is not a registered option, so these
    solves run here rather than on the engine)."""
    from fem_reference.axisym import BLOCK_FACTOR, solve

    from pillar_xval.scenes import load_scene

    path = Path(cache) / f"truncation-{code_version()}.json"
    if path.exists():
        return json.loads(path.read_text())
    out = []
    for name in scene_names:
        scene = load_scene(name)
        vals = {b: quantity_values(solve(scene, 1.0, block_factor=b))
                for b in TRUNCATION_BLOCKS}
        inv = np.array([1.0 / b for b in TRUNCATION_BLOCKS])
        errors = {}
        for q in QKEYS:
            f = np.array([vals[b][q] for b in TRUNCATION_BLOCKS])
            k, f_inf = np.polyfit(inv, f, 1)
            errors[q] = float((k / BLOCK_FACTOR) / f_inf) if f_inf else None
        out.append({"scene": name, "regime": regime(scene)["name"], "errors": errors,
                    "values": {str(b): v for b, v in vals.items()}})
    write_atomic(path, json.dumps(out, indent=1, allow_nan=False))
    return out




def calibrate(out: Path, engine: Engine | None = None, *, n_lattice: int = 40,
              n_stiff: int = 10, seed: int = CALIBRATION_SEED, quick: bool = False,
              lattice: dict | None = None) -> dict:
    """Run (or resume) every calibration study into ``out/cases`` and build the planner's
    data.  ``quick`` shrinks every set to a handful of scenes (for tests); ``lattice`` (a
    :func:`load_lattice` report) supplies the Hooke error in lattices.  Returns
    ``{"errors", "costs", "report"}`` (the two data documents and the measurements)."""
    t0 = time.perf_counter()
    own = engine is None
    engine = engine or Engine("serial", label="calibrate")
    cache = Path(out) / "cases"
    if quick:
        n_lattice, n_stiff = 4, 1
    sample = (lattice_scenes(n_lattice, seed, "pillars", "c")
              + lattice_scenes(n_stiff, seed + 1, "lens", "k") + flat_scenes()[:2 if quick else 4])
    punches = punch_scenes(zetas_um=(0.005, 0.05, 0.5)) if quick else punch_scenes()
    gecit = gecit_scenes((1e-3, 1.0, math.inf), (0.5,), (1.0,)) if quick else \
        gecit_scenes(zetas_um=GECIT_ZETAS_UM)
    try:
        batches = [_cases_of(e) for e in sample]
        punch_batches = [[Case("bem", e["scene"], MODELS["bem"].ladder.options_at(v),
                               tag=f"{e['name']} bem") for v in SINGLE_REFERENCE_RUNGS]
                         + [Case("spring", e["scene"], {}, tag=f"{e['name']} spring")]
                         for e in punches]
        flat = [c for b in batches + punch_batches for c in b]
        outcomes = engine.run(flat, cache, label="calibrate")
        from ..gecit import gecit_study

        # The Hooke BEM refined as for single-pillar references (P = 23, 47, 95): from 11 its
        # centre pressure is pre-asymptotic by ~0.5 % on stiff pillars.
        gecit_doc = gecit_study(gecit, cache, engine=engine, mesh_size=1.0, bem_levels=3,
                                elements_per_diameter=SINGLE_REFERENCE_RUNGS[0])
    finally:
        if own:
            engine.close()
    records, k = [], 0
    for entry, batch in zip(sample + punches, batches + punch_batches):
        records.append(_scene_record(entry, outcomes[k:k + len(batch)]))
        k += len(batch)
    lattice_records, punch_records = records[:len(sample)], records[len(sample):]
    truncation = _truncation(cache)
    tables = (_disc_tables(lattice_records) + _closed_form_tables(lattice_records)
              + [_gecit_table(gecit_doc["rows"], gecit), _punch_table(punch_records)]
              + _truncation_tables(truncation))
    for t in tables:
        t.loo = t.leave_one_out()
    if lattice is not None:
        tables = with_lattice(tables, lattice)
    fits = _cost_fits(_cost_samples(outcomes))
    provenance = {"command": "pillar-xval calibrate", "version": package_version(),
                  "code_version": code_version(), "seed": seed,
                  "scenes": {"lattice": n_lattice, "stiff_substrate": n_stiff,
                             "flat": len(sample) - n_lattice - n_stiff,
                             "gecit": len(gecit), "punch": len(punches),
                             "lattice_study": len(lattice["rows"]) if lattice else 0},
                  "executor": engine.describe(), "wall_time_s": time.perf_counter() - t0,
                  "created": time.strftime("%Y-%m-%dT%H:%M:%S")}
    errors = {"format": DATA_FORMAT, "provenance": provenance, "policy": dict(POLICY),
              "candidates": CANDIDATES, "tables": [t.to_dict() for t in tables]}
    costs = {"format": DATA_FORMAT, "provenance": provenance,
             "models": {m: f.to_dict() for m, f in fits.items()}}
    reference = machine_reference(engine)
    if reference is not None:
        costs["machine"] = reference
    keep_hand_entries(errors, costs)
    report = {"provenance": provenance, "scenes": records, "gecit": gecit_doc["rows"],
              "truncation": truncation,
              "hooke_check": _hooke_check(lattice_records, tables)}
    return {"errors": errors, "costs": costs, "report": report}


def machine_reference(engine: Engine) -> dict | None:
    """This machine's calibration (:mod:`validation.planner.machine`, measured afresh) at
    the threads each case of ``engine`` ran on: the reference the new fits' seconds are
    carried from; None on a remote cluster, whose workers' threads are their own."""
    from ...planner.machine import calibration

    threads = engine.threads
    if threads is None:
        return None
    found = calibration(threads, fresh=True)
    return {"threads": threads, "seconds": found["seconds"],
            "note": "measured by calibrate after its cases, at each case's threads"}




def _hooke_check(records: list, tables: list) -> list:
    """The Gecit grid's Hooke error against the one measured on the sample's single pillars
    (their Hooke and elastic references): an out-of-sample check of that table."""
    table = next(t for t in tables if t.component == "hooke")
    out = []
    for rec in records:
        if rec["regime"] != "single":
            continue
        measured = {q: _relative(rec["references"]["half_space"][q],
                                 rec["references"]["elastic"][q])
                    for q in ("F_T", "sigma0")}
        predicted = {q: table.predict(rec["features"], q)[0] for q in ("F_T", "sigma0")}
        out.append({"name": rec["name"], "measured": measured, "predicted": predicted})
    return out


def write_data(doc: dict, out: Path) -> list:
    """error_models.json, cost_models.json and calibration.json in ``out``."""
    out = Path(out)
    names = {"error_models.json": doc["errors"], "cost_models.json": doc["costs"],
             "calibration.json": doc["report"]}
    for name, content in names.items():
        write_document(out / name, content)
    return list(names)


def write_document(path: Path, content: dict) -> None:
    """``content`` as JSON at ``path`` (atomic), non-finite numbers as null."""
    write_atomic(Path(path), json.dumps(_finite(content), indent=1, allow_nan=False))


def _finite(obj):
    """``obj`` with every non-finite number (a rigid body's modulus, its ratio) as None."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj
