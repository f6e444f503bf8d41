"""``pillar-xval calibrate``: measure the planner's error and cost models.

Every number comes from studies run on the engine (resumable, cached in ``OUT/cases``):

- convergence ladders (the rungs of each candidate model's ladder, :mod:`validation.registry`)
  of the dense and FFT BEM on a seeded Latin-hypercube sample of the paper's scenes (and a
  stiff-substrate one),
  fem-axisym's ladder where one pillar touches, all three on flat scenes.  The discretisation
  error of a rung is measured against a converged reference of the same physics: the Hooke
  pillar's is ``tradeoff``'s cross-checked Richardson estimate from both BEMs
  (:func:`validation.studies.tradeoff.reference_values`), the elastic pillar's the FEM's
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
from ...registry import MODELS, QUANTITIES, candidates, quantity_values
from ...analysis.verification import gci_three
from .scenes import GECIT_ZETAS_UM, flat_scenes, gecit_scenes, lattice_scenes, punch_scenes
from ...planner.costs import size_terms
from ...planner.features import features, regime
from ...planner.tables import DATA_FORMAT, DEFAULT_POLICY, LOO_RELEVANT, CostFit, ErrorTable
from ..tradeoff import reference_values

__all__ = ["CALIBRATION_SEED", "CANDIDATES", "calibrate", "lattice_elastic_rung_tables",
           "lattice_elastic_table",
           "lattice_hooke_table", "load_lattice",
           "relattice", "with_lattice", "write_data", "write_document"]

CALIBRATION_SEED = 20240901
# The planner adds each table's local leave-one-out misfit, times this scale.
POLICY = dict(DEFAULT_POLICY)
QKEYS = [q.key for q in QUANTITIES]
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
# Every candidate without elastic pillars carries the Hooke pillar's error (the closed forms
# too: the spring is a Hooke pillar, the Hertz-like limit is fitted on Hooke lattices).
HOOKE_MODELS = [m.name for m in MODELS.values()
                if m.candidate and m.physics != "elastic-pillar"]


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


def _measured(*args, **kwargs) -> ErrorTable:
    """An error table calibrate measured: its errors keep their signs (``signed``; the
    hand bounds it carries over do not)."""
    return ErrorTable(*args, signed=True, **kwargs)


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




# A lattice study run before rows carried their indentation was at this one.
LATTICE_ZETA_UM = 0.3


def load_lattice(paths) -> dict:
    """One report of ``pillar-xval lattice`` (its ``lattice.json``), or several merged (a
    path, or a list of them: studies at different indentations, or of different parts of a
    grid): every row keeps its own ``zeta_um``, the report's ``zeta_um`` lists them, and a
    scene (Phi, E_p/E_l, convention, zeta) in several files is taken from the first.  InputError naming the file when it is
    missing or not such a report."""
    from pillar_xval.scenes import InputError

    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    if not paths:
        raise InputError("--lattice: expected one or more lattice.json files")
    rows, zetas, seen = [], [], set()
    for path in map(Path, paths):
        try:
            report = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise InputError(f"--lattice {path}: not a readable lattice.json ({exc})") from None
        if not isinstance(report, dict) or not isinstance(report.get("rows"), list):
            raise InputError(f"--lattice {path}: not a report of `pillar-xval lattice` "
                             "(no 'rows')")
        zeta = report.get("zeta_um", LATTICE_ZETA_UM)
        zetas.append(zeta)
        for row in report["rows"]:
            row = {**row, "zeta_um": row.get("zeta_um", zeta)}
            key = (row.get("surface_fraction"), row.get("ratio"), row.get("substrate"),
                   row["zeta_um"])
            if key not in seen:  # a scene two studies share counts once (the first file's)
                seen.add(key)
                rows.append(row)
    if len(paths) == 1:
        return {**report, "rows": rows}
    return {"zeta_um": sorted(set(zetas)), "files": [str(p) for p in paths], "rows": rows}


def _lattice_features(report: dict) -> list:
    """The lattice tables' features: Phi and E_p/E_l; the lens sag over zeta when the
    report's rows span more than one indentation; and the substrate's place between the two
    conventions (``es_share``: 0 at E_s = E_l, 1 at E_s = E_p) when it holds E_s = E_p rows."""
    zetas = {row.get("zeta_um", LATTICE_ZETA_UM) for row in report["rows"]}
    return ["phi", "c_p"] + (["log_sag"] if len(zetas) > 1 else []) \
        + (["es_share"] if _has_paper_rows(report) else [])


def _has_paper_rows(report: dict) -> bool:
    return any(_paper_row(row) for row in report["rows"])


def _paper_row(row: dict) -> bool:
    """An E_s = E_p row that is not also an E_s = E_l one (E_p = E_l)."""
    from ..lattice import LENS

    return row.get("substrate", LENS) != LENS and row.get("ratio") != 1.0


def _lattice_rows(report: dict, names: list):
    """(row, its points) for every converged row the lattice tables use: the E_s = E_l grid,
    and with an ``es_share`` axis the E_s = E_p rows too; a row at E_p = E_l stands for both
    conventions (the same scene), so it gives a point at each end of that axis.  Without the
    axis the E_s = E_p rows are left out (the grid's points would repeat)."""
    from ..lattice import LENS, LatticePoint

    share = "es_share" in names
    for row in report["rows"]:
        paper = _paper_row(row)
        if not row.get("converged") or (row.get("substrate", LENS) != LENS and not paper) \
                or (paper and not share):
            continue
        x = features(LatticePoint(row["surface_fraction"], row["ratio"], row["substrate"]
                                  if paper else LENS,
                                  zeta_um=row.get("zeta_um", LATTICE_ZETA_UM)).scene())
        point = [x[n] for n in names]
        if share and row.get("ratio") == 1.0:
            at = names.index("es_share")
            yield row, [point[:at] + [v] + point[at + 1:] for v in (0.0, 1.0)]
        else:
            yield row, [point]


def _substrate_text(report: dict) -> str:
    return ("E_s = E_l and E_s = E_p (the es_share axis)" if _has_paper_rows(report)
            else "E_s = E_l")


def _zeta_text(report: dict) -> str:
    zetas = sorted({row.get("zeta_um", LATTICE_ZETA_UM) for row in report["rows"]})
    return "zeta = " + ", ".join(f"{z:g}" for z in zetas) + " um"


# A lattice study's fem-3d estimate whose GCI band exceeds this share of it is no reference.
FEM3D_BAND_MAX = 0.02


def _fem_reference_holds(estimate: dict, difference: float = 0.0) -> bool:
    """Whether a lattice study's fem-3d estimate (``fem``, ``fem_band``) can judge a
    ``difference`` from it: its band is within :data:`FEM3D_BAND_MAX` of it, or within the
    difference itself (a difference beyond fem-3d's noise is measured all the same)."""
    fem, band = estimate.get("fem"), estimate.get("fem_band")
    if fem is None or fem == 0 or not math.isfinite(fem):
        return False
    return band is None or abs(band) <= max(FEM3D_BAND_MAX * abs(fem), abs(difference))


def _resolved(error: float, estimate: dict) -> float:
    """A discretisation error measured against fem-3d's estimate, no smaller in magnitude
    than what that estimate resolves: its band over it, but at most
    :data:`~validation.planner.tables.LOO_RELEVANT` (an error below it cannot carry a
    prediction past a useful tolerance, so the floor never raises a table where it matters).
    Without it a table interpolated in log10 takes a chance near-zero (a signed error
    crossing zero at one point: fem-3d's finest level against its own extrapolation, a rung
    whose discretisation cancels its coupling) for a precise one, predicting orders of
    magnitude too small beside it and inflating its neighbours' leave-one-out margins by as
    much (measured: fem-3d mesh_size 1.41 predicted 47 % and 53 % off on two scenes)."""
    fem, band = estimate.get("fem"), estimate.get("fem_band")
    floor = min(abs(band / fem), LOO_RELEVANT) if band is not None and fem else 0.0
    return math.copysign(max(abs(error), floor), error)


def _lattice_errors(report: dict, column: str) -> tuple[list, dict]:
    """(points, errors): (BEM - FEM) / FEM of the lattice study's Richardson estimates in
    ``column`` (``quantities``: the Hooke BEM; ``elastic_quantities``: the elastic-pillar BEM)
    on its Phi x E_p/E_l grid (:func:`_lattice_rows`: E_s = E_l, and E_s = E_p where the
    report has such rows).  A quantity whose estimate is missing or not finite, or whose
    fem-3d estimate's band exceeds both :data:`FEM3D_BAND_MAX` of it and the difference
    itself (no asymptotic range, and a difference inside fem-3d's noise: no measurement of
    the BEM's error), is left out at that point."""
    points, errors = [], {q: [] for q in QKEYS}
    for row, xs in _lattice_rows(report, _lattice_features(report)):
        for x in xs:
            points.append(x)
            for q in QKEYS:
                v = (row.get(column) or {}).get(q) or {}
                fem, bem = v.get("fem"), v.get("bem")
                est = {"fem": fem, "fem_band": ((row.get("quantities") or {}).get(q) or {})
                       .get("fem_band")}
                ok = fem is not None and bem is not None and math.isfinite(bem) \
                    and _fem_reference_holds(est, bem - fem)
                errors[q].append((bem - fem) / fem if ok else None)
    return points, errors


def lattice_hooke_table(report: dict) -> ErrorTable:
    """The Hooke pillar's error in a lattice: the Hooke bem-fft against fem-3d
    (:func:`_lattice_errors`)."""
    points, errors = _lattice_errors(report, "quantities")
    return _measured(
        "model", [m for m in HOOKE_MODELS if "multi" in MODELS[m].scopes], ["multi"],
        _lattice_features(report), points, errors,
        component="hooke",
        source="lattice: Hooke-pillar bem-fft (Richardson) against the elastic-pillar fem-3d "
               "(Richardson)",
        note=f"measured at {len(points)} lattice points, {_substrate_text(report)}, "
             f"{_zeta_text(report)}; other substrates take these values (the Gecit grid "
             "measures the substrate's share on one pillar)")


def lattice_elastic_table(report: dict) -> ErrorTable | None:
    """The elastic-pillar BEM's model error in a lattice (its pillars coupled through the
    half-space at the top plane): its bem-fft column against fem-3d, or None when the report
    has no elastic column."""
    if not any(r.get("elastic_quantities") for r in report["rows"]):
        return None
    points, errors = _lattice_errors(report, "elastic_quantities")
    return _measured(
        "model", ["bem", "bem-fft"], ["multi"], _lattice_features(report), points, errors,
        component="elastic-coupling", option={"pillars": "elastic"},
        source="lattice: elastic-pillar bem-fft (Richardson) against the elastic-pillar "
               "fem-3d (Richardson)",
        note=f"measured at {len(points)} lattice points, {_substrate_text(report)}, "
             f"{_zeta_text(report)}; what "
             "remains of the pillars' coupling through the substrate beyond its second-moment correction (largest for stiff pillars on "
             "a soft substrate in dense lattices); scenes at E_s = E_p, where the study "
             "measured it smaller, take these values (conservative)")


def _level_errors(report: dict, column: str, option: str, judge_difference: bool) -> dict:
    """{option value: (points, errors)}: each level in the rows' ``column`` (its ``option``
    names it) against the row's fem-3d Richardson estimate, signed and floored at what that
    estimate resolves (:func:`_resolved`), on the lattice rows (:func:`_lattice_rows`).  A level
    that did not converge, or whose estimate cannot judge it (:func:`_fem_reference_holds`;
    ``judge_difference``: a difference beyond the band counts all the same, as for another
    model; not for fem-3d's own levels, whose differences from the estimate are the
    extrapolation itself), holds None at that point."""
    levels = {}
    for row, xs in _lattice_rows(report, _lattice_features(report)):
        for level in row.get(column) or ():
            points, errors = levels.setdefault(level[option], ([], {q: [] for q in QKEYS}))
            for x in xs:
                points.append(x)
                for q in QKEYS:
                    est = (row.get("quantities") or {}).get(q) or {}
                    v, fem = level.get(q), est.get("fem")
                    ok = level.get("converged", False) and v is not None \
                        and math.isfinite(v) and fem is not None \
                        and _fem_reference_holds(est, v - fem if judge_difference else 0.0)
                    errors[q].append(_resolved((v - fem) / fem, est) if ok else None)
    return levels


def lattice_fem3d_tables(report: dict) -> list:
    """fem-3d's discretisation error in a lattice, one table per mesh_size of the lattice
    study's ladder: each level against the study's Richardson estimate of fem-3d over that
    ladder (:func:`_level_errors`); empty when the report has no fem-3d levels."""
    levels = _level_errors(report, "fem_levels", "mesh_size", judge_difference=False)
    ladder = ", ".join(f"{m:g}" for m in sorted(levels, reverse=True))
    return [_measured(
        "discretisation", ["fem-3d"], ["multi"], _lattice_features(report), points, errors,
        option={"mesh_size": mesh_size},
        source=f"lattice: fem-3d at mesh_size {mesh_size:g} against its Richardson estimate "
               f"over mesh_size {ladder}",
        note=f"measured at {len(points)} lattice points, {_substrate_text(report)}, "
             f"{_zeta_text(report)}; other substrates take these values")
        for mesh_size, (points, errors) in sorted(levels.items()) if len(points) >= 3]


# The elastic-pillar BEMs' rungs in a lattice report: (model, option) -> the rows' columns
# (the bem-fft's ladder and its single rungs between the ladder's levels).
ELASTIC_RUNGS = {("bem-fft", "cells_per_diameter"): ("elastic_levels", "elastic_fft_rungs"),
                 ("bem", "elements_per_diameter"): ("elastic_dense_levels",)}


def lattice_elastic_rung_tables(report: dict) -> list:
    """The elastic-pillar BEMs' error in a lattice at each of the planner's rungs, measured
    directly: each level of the study's elastic bem-fft ladder, each of its single rungs and
    each dense elastic level against fem-3d's Richardson estimate (:func:`_level_errors`).
    One table per rung, of kind ``discretisation`` with the rung's option and ``pillars =
    elastic``: the error it holds is the whole error against the reference of the same
    physics (the elastic pillar), so its discretisation and what remains of its coupling
    through the substrate together, and no coupling table is added on top
    (:func:`with_lattice`)."""
    out = []
    for (model, option), columns in ELASTIC_RUNGS.items():
        levels = {}
        for column in columns:
            levels.update(_level_errors(report, column, option, judge_difference=True))
        out += [_measured(
            "discretisation", [model], ["multi"], _lattice_features(report), points, errors,
            option={option: value, "pillars": "elastic"},
            source=f"lattice: elastic-pillar {model} at {option} {value} against the "
                   "elastic-pillar fem-3d (Richardson)",
            note=f"measured at {len(points)} lattice points, {_substrate_text(report)}, "
                 f"{_zeta_text(report)}; the "
                 "whole error against fem-3d (discretisation and the pillars' coupling "
                 "together); other substrates take these values")
            for value, (points, errors) in sorted(levels.items()) if len(points) >= 3]
    return out


def with_lattice(tables: list, report: dict) -> list:
    """``tables`` with the lattice study's tables for multi-pillar scenes: the Hooke table
    (the Gecit grid's Hooke table keeps the single-pillar regime only); the elastic BEMs'
    error at each of their rungs (:func:`lattice_elastic_rung_tables`); for an elastic BEM
    whose rungs the report does not hold, the elastic BEM's coupling table in place of any
    other multi-pillar coupling table (a hand bound); and fem-3d's discretisation per
    mesh_size in place of its hand bounds."""
    from dataclasses import replace

    rungs = lattice_elastic_rung_tables(report)
    elastic = lattice_elastic_table(report)
    if elastic is not None:
        tables = [t for t in tables
                  if not (t.component == "elastic-coupling" and "multi" in t.regimes)]
        # A model whose rungs have their own tables carries its coupling in them.
        with_rungs = {m for t in rungs for m in t.models}
        elastic.models = [m for m in elastic.models if m not in with_rungs]
        elastic = elastic if elastic.models else None
    fem3d = lattice_fem3d_tables(report)
    measured_sizes = [t.option for t in fem3d]
    tables = [t for t in tables  # a measured fem-3d table displaces the hand bound
              if not ("fem-3d" in t.models and t.kind == "discretisation"
                      and "multi" in t.regimes and t.option in measured_sizes)]
    out = [replace(t, regimes=[r for r in t.regimes if r != "multi"],
                   note="measured on one pillar; multi-pillar scenes use the lattice study's "
                        "table")
           if t.component == "hooke" and "multi" in t.regimes else t for t in tables]
    new = ([lattice_hooke_table(report)] + ([elastic] if elastic is not None else []) + fem3d
           + rungs)
    for t in new:
        t.loo = t.leave_one_out()
    return out + new


def relattice(errors: dict, report: dict, source: str = "") -> dict:
    """An ``error_models.json`` document with its lattice Hooke table replaced by one from
    ``report`` (``calibrate --lattice F --lattice-only``: a rerun lattice study updates the
    planner without re-running the other calibration studies).  Every table's margins are
    recomputed from its own points (:meth:`ErrorTable.leave_one_out`, a function of the
    table alone), so they follow the current rule."""
    tables = [ErrorTable(**t) for t in errors["tables"]]
    tables = [t for t in tables if not t.source.startswith("lattice")]
    for t in tables:  # the lattice tables get theirs in with_lattice
        t.loo = t.leave_one_out()
    tables = with_lattice(tables, report)
    prov = dict(errors["provenance"])
    prov["scenes"] = {**prov.get("scenes", {}), "lattice_study": len(report["rows"])}
    prov["lattice_study"] = {"file": source, "rows": len(report["rows"]),
                             "added": time.strftime("%Y-%m-%dT%H:%M:%S"),
                             "how": "calibrate --lattice-only: the calibration above, its "
                                    "multi-pillar Hooke table from this lattice study"}
    return {**errors, "provenance": prov, "tables": [t.to_dict() for t in tables]}


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


def _cost_fits(samples: list) -> dict:
    """One fit per model with a cost law (its declaration's ``cost``: time =
    sum_k c_k n^p_k, :class:`validation.planner.tables.CostFit`; nonnegative coefficients,
    least squares in ln(time)), and the FFT's memory per padded point."""
    from scipy.optimize import least_squares

    fits = {}
    for model, law in ((m.name, m.cost) for m in MODELS.values() if m.cost is not None):
        size, term, powers, memory = law.size, law.term, list(law.powers), law.memory
        option = _cost_option(model)
        mine = [s for s in samples if s["model"] == model and s["wall_time_s"] > 0]
        if not mine:
            continue
        n = np.array([math.exp(s["terms"][term]) if term else 1.0 for s in mine])
        y = np.log([s["wall_time_s"] for s in mine])
        basis = np.column_stack([n**p for p in powers])

        def residual(log_c):
            return np.log(basis @ np.exp(log_c)) - y

        # start from each law's share of the largest runs
        start = [float(np.median(y))] + [float(np.median(y) - p * np.log(n.max()))
                                         for p in powers[1:]]
        sol = least_squares(residual, start)
        coef = [float(c) for c in np.exp(sol.x)]
        rms = float(np.sqrt(np.mean(sol.fun**2)))
        if memory is None:
            mem = [s["peak_memory_MB"] * 2**20 for s in mine if s["peak_memory_MB"]]
            if term == "log_points" and mem:
                pts = np.array([math.exp(s["terms"]["log_points"]) for s in mine
                                if s["peak_memory_MB"]])
                slope, fixed = np.polyfit(pts, mem, 1)
                memory = {"kind": "per_point", "fixed": float(max(fixed, 0.0)),
                          "per_point": float(max(slope, 0.0))}
            else:
                memory = {"kind": "fixed", "fixed": float(np.median(mem)) if mem else 0.0}
        fits[model] = CostFit(model, size, option, term, list(powers), coef, rms, memory,
                              len(mine), workload=dict(law.workload))
    return fits


def _cost_option(model: str) -> str | None:
    """The option a model's cost law reads: its ladder's."""
    ladder = MODELS[model].ladder
    return ladder.option if ladder is not None else None


def _cost_samples(outcomes: list) -> list:
    out = []
    for o in outcomes:
        if not o.ok:
            continue
        law = MODELS[o.case.model].cost
        size, option = (law.size, _cost_option(o.case.model)) if law else ("none", None)
        value = o.case.options.get(option) if option else None
        terms, _ = size_terms(size, o.case.scene, value)
        out.append({"model": o.case.model, "terms": terms,
                    "wall_time_s": o.timing["wall_time_s"],
                    "peak_memory_MB": o.timing.get("peak_memory_MB")})
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


HAND = "hand"


def is_hand(entry: dict, key: str = "source") -> bool:
    """Whether a data entry (candidate, table, cost fit) was written by hand, not measured."""
    return str(entry.get(key, "")).startswith(HAND)


def keep_hand_entries(errors: dict, costs: dict, folder: Path | None = None) -> None:
    """Carry the installed data's hand entries (``source``/``note`` starting with "hand":
    fem-3d and the elastic-pillar BEMs as candidates) into a new calibration that
    does not measure them yet: candidates, error tables, cost fits and cost variants that the
    calibration did not write itself.  ``folder``: the installed data (default the
    package's)."""
    from ...planner.tables import data_dir

    folder = Path(folder) if folder is not None else data_dir()
    try:
        old_errors = json.loads((folder / "error_models.json").read_text())
        old_costs = json.loads((folder / "cost_models.json").read_text())
    except (OSError, ValueError):
        return
    labels = {c["label"] for c in errors["candidates"]}
    errors["candidates"] = list(errors["candidates"]) + [
        c for c in old_errors.get("candidates", ())
        if is_hand(c) and c["label"] not in labels]
    def measured(t):  # the calibration measured this table itself (e.g. from the lattice),
        # or a more specific one that holds it: an elastic rung's whole error against fem-3d
        # holds the coupling a hand bound stood for
        def covers(m):
            same = m.get("component") == t.get("component") and m.get("option") == t.get("option")
            specific = m.get("source", "").startswith("lattice") and t.get("option") and \
                t["option"].items() < m.get("option", {}).items()
            return (same or specific) and set(m.get("regimes", ())) & set(t.get("regimes", ())) \
                and set(m.get("models", ())) & set(t.get("models", ()))
        return any(covers(m) for m in errors["tables"])

    errors["tables"] = list(errors["tables"]) + [
        t for t in old_errors.get("tables", ()) if is_hand(t)
        and t not in errors["tables"] and not measured(t)]
    for name, fit in old_costs.get("models", {}).items():
        if name not in costs["models"] and is_hand(fit, "note"):
            # its seconds are of the machine the installed data was measured on
            costs["models"][name] = {"machine": old_costs.get("machine", {}), **fit}
    variants = {k: v for k, v in old_costs.get("variants", {}).items()
                if is_hand(v, "note") and v["base"] in costs["models"]}
    if variants:
        costs["variants"] = variants
    hand = old_errors.get("provenance", {}).get("hand_entries")
    if hand:
        errors["provenance"] = {**errors["provenance"], "hand_entries": hand}


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
