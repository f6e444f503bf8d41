"""The paper's Figs. 3-8 from one call: :func:`run_figures`.

Every scene of :mod:`.scenes` runs as one batch on the engine (cached under
``out/cases``: a rerun resumes), longest first so the pool ends evenly; then the single-pillar
threshold is bisected on the exact solver (:mod:`.thresholds`), the master curves are
fitted (:mod:`.fits`), and each figure is written as a PNG with the CSV of its data
(:mod:`.plots`), beside ``figures.json`` (every number), ``figures.md`` (the paper's
numbers beside ours, :mod:`.report`) and ``timing.json``.

``pillars = "elastic"`` or ``"both"`` runs the scenes and the bisection with the elastic-pillar
BEM as well (the model's option ``pillars``, named in every case, Hooke ones included).
Every elastic scene of the figures has E_s = E_p and Table 1's h/d and nu: one pillar kind,
whose compliance is built (or read from the disk cache) once before the batch.

How the paper's thresholds are fitted here: for each (zeta, E_p/E_l), sigma_0H is the Hertz
value of eq. S0Hertz and sigma_0S the solver's own single-pillar plateau (sigma_0 at the
smallest Phi, where one pillar touches and sigma_0 no longer depends on Phi: the paper takes
both "numerically for Phi ~ 1 and Phi ~ 0", and the solver cannot reach Phi = 1); Phi_S and
Phi_H are fitted to sigma_0*(Phi) with (1 + Phi*)^-3.  The toolkit's own thresholds: the
largest Phi with one pillar in contact (bisection), and the Phi where sigma_0 comes within
``band`` of sigma_0H.
"""

from __future__ import annotations

import json
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import Scene

from ...engine import Case, Engine
from .files import write_figures
from .fits import (exponent_profile, fit_area_exponent, fit_common_exponent,
                           fit_thresholds, hertz_band_entry, master_curve, reduced_area,
                           reduced_pressure)
from .scenes import (FIG3_ZETA_UM, FigureGrid, expected_pillars, figure_sweeps,
                             pillar_height, table1_scene)
from .scenes import in_um as _um
from .thresholds import analytic_thresholds, bisect_single_pillar

__all__ = ["DENSE_MODELS", "HERTZ_BAND", "pillar_variants", "run_figures", "variant_options"]

# The maps of Fig. 3 are drawn from the dense model's elements.
DENSE_MODELS = ("bem", "bem-richardson")
# sigma_0 "within the band of Hertz": |sigma_0 / sigma_0H - 1| <= 10 %.  Ten times the
# figures' 1 % discretisation tolerance, so no threshold is a discretisation artefact, and
# wider than the 4 % by which the paper's own Phi = 0.82 scene (8 kPa against 8.3 kPa)
# counts as "very close to the true Hertz value".
HERTZ_BAND = 0.10


def _ratio(scene: Scene) -> float:
    return float(f"{scene.pillars.material.E_Pa / scene.lens.material.E_Pa:.6g}")


def _row(sweep_case, outcome) -> dict:
    scene = sweep_case.scene
    row = {"ratio": _ratio(scene), "phi": sweep_case.point.get(
        "pillars.surface_fraction", scene.pillars.surface_fraction),
        "zeta_m": scene.indentation_m, "E_p_Pa": scene.pillars.material.E_Pa,
        "ok": outcome.ok, "converged": False, "status": "ok" if outcome.ok else
        f"failed: {outcome.error}"}
    if outcome.ok:
        r = outcome.result
        row.update(sigma0_Pa=r.centre_pressure_Pa, F_N=r.total_force_N, a_m=r.contact_radius_m,
                   A_m2=r.real_contact_area_m2, pillars=r.pillars_in_contact,
                   converged=bool(r.converged), wall_time_s=outcome.timing.get("wall_time_s"))
    return row


def _listed(sweeps: dict) -> dict:
    """Every case of every sweep, Fig. 3's with their arrays."""
    import dataclasses

    listed = {}
    for name, sweep in sweeps.items():
        cases, _ = sweep.cases()
        if name == "fig3":
            cases = [dataclasses.replace(c, case=dataclasses.replace(c.case, fields=True))
                     for c in cases]
        listed[name] = cases
    return listed


def _curve_fit(rows: list[dict], zeta_um: float, ratio: float, band: float) -> dict:
    """Fitted Phi_S, Phi_H (n = 3) and the Hertz-band entry of one sigma_0(Phi) curve."""
    rows = sorted((r for r in rows if r.get("converged")), key=lambda r: r["phi"])
    if len(rows) < 3:
        return None
    closed = analytic_thresholds(zeta_um, ratio)
    s_h = closed["sigma0_hertz_Pa"]
    single = rows[0]
    s_s = single["sigma0_Pa"] if single["pillars"] == 1 else closed["sigma0_single_Pa"]
    phi = np.array([r["phi"] for r in rows])
    s0 = np.array([r["sigma0_Pa"] for r in rows])
    star = reduced_pressure(s0, s_h, s_s)
    fit = fit_thresholds(phi, star)
    entry = hertz_band_entry(phi, s0, s_h, band)
    return {"ratio": ratio, "zeta_um": zeta_um, "zeta_h": None, "phi": phi.tolist(),
            "sigma0_Pa": s0.tolist(), "star": star.tolist(), "sigma0_hertz_Pa": s_h,
            "sigma0_single_Pa": s_s, "single_from": "solver" if single["pillars"] == 1
            else "eq. S0SFP (no single-pillar point)",
            "sigma0_single_closed_Pa": closed["sigma0_single_Pa"],
            "phi_s_fit": fit["phi_s"], "phi_h_fit": fit["phi_h"], "fit_rms": fit["rms"],
            "phi_h_band": entry["phi"], "band_stays": entry["stays"],
            "band_lowest": entry["lowest"]}


def _curves(rows: list[dict], band: float) -> list[dict]:
    """One fitted curve per (E_p/E_l, zeta) of ``rows``."""
    groups = defaultdict(list)
    for r in rows:
        groups[(r["ratio"], _um(r["zeta_m"]))].append(r)
    out = []
    for (ratio, zeta_um), rs in sorted(groups.items()):
        c = _curve_fit(rs, zeta_um, ratio, band)
        if c is None:  # fewer than three converged points: nothing to fit
            continue
        c["zeta_h"] = zeta_um * 1e-6 / pillar_height()
        out.append(c)
    return out


def pillar_variants(pillars) -> tuple[str, ...]:
    """The pillar models of a figures run: ``"hooke"`` (default), ``"elastic"``, ``"both"``
    (or a comma list / sequence), in the declaration's order.  InputError (one line naming
    --pillars, the value and the allowed values) otherwise."""
    from ...registry.options import pillar_models

    return pillar_models(pillars)


def variant_options(options: dict, pillars: str) -> dict:
    """The model's options for one pillar model, named even for the paper's Hooke spring: a
    sweep gives a scene with elastic pillars the elastic pillar where none is named."""
    return {**options, "pillars": pillars}


def _pillar_kinds(batch: list[Case]) -> list:
    """The distinct pillar kinds (h/d, E_p/E_s, nu_p, nu_s) of the elastic-pillar cases."""
    from fem_reference import PillarKind

    from bem_solver._elastic_pillar import uses_elastic_block

    kinds = {}
    for c in batch:
        if uses_elastic_block(c.scene, c.options.get("pillars", "hooke")):
            kinds.setdefault(PillarKind.of_scene(c.scene), c.scene)
    return list(kinds.items())


def _build_compliances(batch: list[Case]) -> dict:
    """Build (or read from the disk cache) each pillar kind's compliance once, here, before
    the batch: the workers then read it from the cache instead of racing to build it."""
    from bem_solver._elastic_pillar import scene_compliance

    t0 = time.perf_counter()
    kinds = _pillar_kinds(batch)
    built = []
    for kind, scene in kinds:
        c = scene_compliance(scene)
        built.append({"height_over_diameter": kind.height_over_diameter,
                      "modulus_ratio": kind.modulus_ratio, "nu_pillar": kind.nu_pillar,
                      "nu_substrate": kind.nu_substrate,
                      "cached": bool(c.diagnostics.get("cached"))})
    return {"pillar_kinds": len(kinds), "pillar_kinds_built": sum(not b["cached"] for b in built),
            "pillar_compliance_s": time.perf_counter() - t0, "kinds": built}


def run_figures(out: Path, grid: FigureGrid | None = None, *, model: str = "bem-richardson",
                options: dict | None = None, engine: Engine | None = None,
                band: float = HERTZ_BAND, pillars="hooke") -> dict:
    """Solve every scene of the figures, fit, plot and report into ``out``.

    Parameters
    ----------
    out : Path
        Folder for the PNGs, CSVs, ``figures.json``, ``figures.md``, ``claims.csv``,
        ``timing.json`` and the case cache ``cases/``.
    grid : FigureGrid
        The swept values (default :meth:`FigureGrid.full`).
    model, options : str, dict
        A dense model (``bem-richardson`` or ``bem``) and its options for Figs. 4-8.
    engine : Engine
        Where the cases run (default: serial).
    band : float
        Relative band of the Hertz threshold (module docstring).
    pillars : str
        ``"hooke"`` (the paper's spring, default), ``"elastic"`` (the elastic-pillar BEM) or
        ``"both"``: every scene and the bisection with each, one batch on the engine, drawn on
        the same axes and checked claim by claim in ``figures.md`` (:mod:`.claims`).

    Returns
    -------
    dict
        Everything written to ``figures.json``, plus ``paths`` (the files written).  One
        pillar model: the variant's document (``pillars`` names it); several: ``variants``
        (one such document per pillar model) beside ``pillars``, ``claims``, ``timing``.
    """
    from .claims import claim_rows, write_claims_csv
    from .report import write_report

    t_start = time.perf_counter()
    out = Path(out)
    variants = pillar_variants(pillars)
    grid = grid or FigureGrid.full()
    options = {"elements_per_diameter": grid.elements_per_diameter, **(options or {})}
    own = engine is None
    engine = engine or Engine("serial")
    timing = {}
    try:
        listed, extras = {}, {}
        for v in variants:
            sweeps = figure_sweeps(grid, model, variant_options(options, v))
            dense = next(c.scene for c in sweeps["fig3"].cases()[0]
                         if c.scene.pillars.surface_fraction > 0.5)
            search = variant_options({"elements_per_diameter":
                                      grid.search_elements_per_diameter}, v)
            extras[v] = [Case("bem", dense, {**search, "contact": c},
                              tag=f"Fig. 3b, {c} contact, {v} pillars")
                         for c in ("exact", "paper")]
            listed[v] = _listed(sweeps)
        batch = [c.case for v in variants for cs in listed[v].values() for c in cs] + \
            [c for v in variants for c in extras[v]]
        t0 = time.perf_counter()
        if "elastic" in variants:
            timing.update(_build_compliances(batch))
        batch.sort(key=lambda c: -expected_pillars(c.scene))
        outcomes = engine.run(batch, out / "cases", label="figures")
        by_key = {case.key: o for case, o in zip(batch, outcomes)}
        timing["scenes_s"] = time.perf_counter() - t0
        pairs = {v: {name: [(c, by_key[c.case.key]) for c in cs]
                     for name, cs in listed[v].items()} for v in variants}
        extra_out = {v: [by_key[c.key] for c in extras[v]] for v in variants}
        rows = {v: {name: [_row(c, o) for c, o in p] for name, p in pairs[v].items()}
                for v in variants}

        t0 = time.perf_counter()
        exact = {}
        for v in variants:
            points = sorted({(_um(r["zeta_m"]), r["ratio"]) for r in rows[v]["master"]}
                            | {(z, ratio) for z in grid.threshold_extra_zetas_um
                               for ratio in grid.ratios})
            exact[v] = bisect_single_pillar(points, engine, out / "cases",
                                            grid.threshold_elements_per_diameter,
                                            grid.threshold_steps,
                                            options=variant_options({}, v))
        timing["threshold_bisection_s"] = time.perf_counter() - t0
    finally:
        if own:
            engine.close()

    t0 = time.perf_counter()
    # One BLAS thread: the fits' small SVDs are 100x slower when OpenBLAS threads spin on a
    # loaded machine (measured: 0.5 s for a 600 x 61 Jacobian).
    with threadpool_limits(limits=1, user_api="blas"):
        docs = {v: _analyse(grid, model, variant_options(options, v), rows[v], pairs[v],
                            extra_out[v], exact[v], band) for v in variants}
        for v in variants:
            docs[v]["pillars"] = v
        paths = [str(p) for p in write_figures(out, docs, pairs)]
    timing["analysis_and_plots_s"] = time.perf_counter() - t0
    computed = [o for v in variants for p in pairs[v].values() for _, o in p
                if o.ok and not o.cached]
    timing.update({
        "total_s": time.perf_counter() - t_start,
        "pillars": list(variants),
        "cases": sum(len(p) for v in variants for p in pairs[v].values()),
        "unique_cases": len({c.case.key for v in variants for p in pairs[v].values()
                             for c, _ in p}),
        "cases_computed": len({o.case.key for o in computed}),
        "threshold_solves": sum(e["solves"] for v in variants for e in exact[v]),
        "case_wall_time_sum_s": float(sum(o.timing.get("wall_time_s", 0.0) for o in computed)),
        "executor": engine.describe(), "workers": engine.workers,
    })
    if len(variants) == 1:
        doc = docs[variants[0]]
    else:
        first = docs[variants[0]]
        doc = {"pillars": list(variants), "grid": first["grid"], "model": model,
               "options": options, "variants": docs,
               "failed": [{**f, "pillars": v} for v in variants for f in docs[v]["failed"]]}
    doc["claims"] = claim_rows(docs)
    doc["timing"] = timing
    doc["paths"] = paths
    write_atomic(out / "timing.json", json.dumps(timing, indent=2) + "\n")
    doc["paths"] += [str(out / "timing.json")]
    doc["paths"] += [str(write_claims_csv(out, doc["claims"], variants, grid.name))]
    doc["paths"] += [str(p) for p in write_report(out, doc)]
    write_atomic(out / "figures.json", json.dumps(doc, indent=1, default=float) + "\n")
    return doc


def _analyse(grid, model, options, rows, pairs, extra_out, exact, band) -> dict:
    curves = _curves(rows["master"], band)
    fig4a = _curves(rows["fig4a"], band)
    common = fit_common_exponent([(c["phi"], c["star"]) for c in curves])
    n3 = np.concatenate([master_curve(c["phi"], c["phi_s_fit"], c["phi_h_fit"])
                         - np.asarray(c["star"]) for c in curves])
    common["rms_n3"] = float(np.sqrt(np.mean(n3**2)))
    common["profile"] = exponent_profile([(c["phi"], c["star"]) for c in curves])
    points = []
    by_curve = {(c["ratio"], c["zeta_um"]): c for c in curves}
    table1 = table1_scene(0.01, FIG3_ZETA_UM, 1.0)
    radius, diameter = table1.lens.radius_m, table1.pillars.diameter_m
    top = np.pi * diameter**2 / 4.0
    for r in rows["master"]:
        if not r.get("converged"):
            continue
        c = by_curve.get((r["ratio"], _um(r["zeta_m"])))
        if c is None:
            continue
        points.append({
            "ratio": r["ratio"], "zeta_m": r["zeta_m"], "phi": r["phi"],
            "phi_star": (r["phi"] - c["phi_s_fit"]) / c["phi_h_fit"],
            "sigma_star": float(reduced_pressure(r["sigma0_Pa"], c["sigma0_hertz_Pa"],
                                                 c["sigma0_single_Pa"])),
            "area_star": float(reduced_area(r["A_m2"], radius, r["zeta_m"], diameter)),
            "area_star_tops": float(reduced_area(r["pillars"] * top, radius, r["zeta_m"],
                                                 diameter))})
    phis = [p["phi"] for p in points]
    area = fit_area_exponent(phis, [p["area_star"] for p in points])
    area["tops"] = fit_area_exponent(phis, [p["area_star_tops"] for p in points])
    h = pillar_height()
    for e in exact:
        closed = analytic_thresholds(e["zeta_um"], e["ratio"])
        e.update(zeta_h=e["zeta_um"] * 1e-6 / h, phi_s_paper=closed["phi_s_paper"],
                 phi_s_rim=closed["phi_s_rim"], phi_s_large_zeta=closed["phi_s_large_zeta"])
    zetas = sorted({e["zeta_um"] for e in exact})
    thresholds = {
        "band": band, "curves": curves, "exact": exact,
        "large_zeta": {"zeta_h": [z * 1e-6 / h for z in zetas],
                       "phi_s": [analytic_thresholds(z, 1.0)["phi_s_large_zeta"] for z in zetas]},
        "zeta_t_over_h": {str(r): analytic_thresholds(0.3, r)["zeta_t_over_h"]
                          for r in sorted({*grid.ratios, *grid.fig4a_ratios})},
        "common_exponent": {k: common[k] for k in ("exponent", "rms", "rms_n3", "profile")},
        "area_exponent": area,
    }
    fig3 = []
    for c, o in pairs["fig3"]:
        fig3.append({"phi": c.scene.pillars.surface_fraction, "ok": o.ok,
                     **({} if not o.ok else _summary(o.result))})
    search = [_summary(o.result) if o.ok else {"error": str(o.error)} for o in extra_out]
    failed = [r for rs in rows.values() for r in rs if not r["ok"] or not r["converged"]]
    return {"grid": grid.to_dict(), "model": model, "options": options,
            "rows": rows, "fig4a_curves": fig4a, "thresholds": thresholds,
            "master_points": points, "fig3": fig3, "fig3_search": search,
            "failed": [{k: r[k] for k in ("ratio", "phi", "zeta_m", "status", "converged")}
                       for r in failed]}


def _summary(r) -> dict:
    return {"sigma0_Pa": r.centre_pressure_Pa, "F_N": r.total_force_N, "a_m": r.contact_radius_m,
            "A_m2": r.real_contact_area_m2, "pillars": r.pillars_in_contact,
            "contact": r.discretisation.get("contact", "exact"),
            "elements_per_diameter": r.discretisation.get("elements_per_diameter"),
            "max_interpenetration_m": r.diagnostics.get("max_interpenetration_m", 0.0),
            "min_pressure_Pa": r.diagnostics.get("min_pressure_Pa", 0.0)}
