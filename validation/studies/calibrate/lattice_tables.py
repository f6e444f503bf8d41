"""The planner's lattice tables from a report of ``pillar-xval lattice``: the Hooke pillar's
error in a lattice, the elastic BEMs' and fem-3d's levels (``calibrate --lattice``,
``relattice``)."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path



from ...registry import MODELS
from ...planner.features import features
from ...planner.tables import LOO_RELEVANT, ErrorTable
from .measured import HOOKE_MODELS, QKEYS, _measured


# The indentation of a report whose rows do not carry theirs: the study's default.
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
