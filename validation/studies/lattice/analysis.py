"""A lattice point's ladders: Richardson estimates, ring and profile comparisons, the
elastic BEM's targets, and the row of one point."""

from __future__ import annotations

import numpy as np

from pillar_xval.scenes import InputError, lattice

from ...analysis.verification import study
from ...registry import QUANTITIES, quantity_values
from .._ladder import estimate, profile_key, profile_studies
from ..targets import TARGETS, judge
from .points import BEM_NAMES, ELASTIC, FEM_MODEL, HOOKE, PROFILE_POINTS, LatticePoint


def _single_levels(outcomes, option: str) -> list[dict]:
    """An elastic BEM's single levels (its ``option`` names each): each one's quantities, or
    the error that stopped it (a failed level is reported, not judged)."""
    out = []
    for o in outcomes:
        level = {option: o.case.options[option]}
        if o.ok:
            level.update(converged=bool(o.result.converged),
                         wall_time_s=o.result.wall_time_s, **quantity_values(o.result))
        else:
            level.update(converged=False, error=str(o.error))
        out.append(level)
    return out


def _ladder(outcomes, option, h_power) -> dict:
    """Levels of one model (coarse to fine) and the study of each quantity."""
    done = [o for o in outcomes if o.ok]
    if len(done) < 2:
        errors = [o.error for o in outcomes if not o.ok]
        return {"levels": [], "studies": {}, "results": [],
                "error": "; ".join(str(e) for e in errors) or "no level",
                # exit status of the failure: 2 if the model refused the scene, else 3
                "exit": 2 if errors and all(isinstance(e, InputError) for e in errors) else 3}
    values = [o.case.options[option] for o in done]
    h = [float(v) ** h_power for v in values]
    rows = [{option: v, "h": hh, "converged": bool(o.result.converged),
             "wall_time_s": o.result.wall_time_s, **quantity_values(o.result)}
            for v, hh, o in zip(values, h, done)]
    studies = {q.key: study(h, [r[q.key] for r in rows]) for q in QUANTITIES}
    return {"levels": rows, "studies": studies, "results": [o.result for o in done],
            "error": None}


def ring_ratios(fem_result, bem_result) -> list[dict]:
    """FEM/BEM force ratio of every pillar both load, by ring: mean, min, max, count, and the
    pillars only one model loads."""
    fem = {(p.n, p.m): p.force_N for p in fem_result.pillar_forces}
    bem = {(p.n, p.m): p.force_N for p in bem_result.pillar_forces}
    rings: dict[int, dict] = {}
    for nm in set(fem) | set(bem):
        k = lattice.ring(*nm)
        r = rings.setdefault(k, {"ring": k, "ratios": [], "fem_only": 0, "bem_only": 0,
                                 "fem_force_N": 0.0, "bem_force_N": 0.0})
        r["fem_force_N"] += fem.get(nm, 0.0)
        r["bem_force_N"] += bem.get(nm, 0.0)
        if nm in fem and nm in bem and bem[nm] > 0:
            r["ratios"].append(fem[nm] / bem[nm])
        elif nm in fem:
            r["fem_only"] += 1
        else:
            r["bem_only"] += 1
    out = []
    for k in sorted(rings):
        r = rings[k]
        ratios = np.asarray(r.pop("ratios"))
        r.update({"pillars": int(ratios.size),
                  "ratio_mean": float(ratios.mean()) if ratios.size else None,
                  "ratio_min": float(ratios.min()) if ratios.size else None,
                  "ratio_max": float(ratios.max()) if ratios.size else None,
                  "ring_force_ratio": r["fem_force_N"] / r["bem_force_N"]
                  if r["bem_force_N"] > 0 else None})
        out.append(r)
    return out


def _rings(fem: dict, bem: dict) -> list[dict]:
    """:func:`ring_ratios` of the finest levels, with each ring's change from the next-coarser
    pair of levels."""
    rings = ring_ratios(fem["results"][-1], bem["results"][-1])
    if len(fem["results"]) >= 2 and len(bem["results"]) >= 2:
        coarser = {r["ring"]: r for r in ring_ratios(fem["results"][-2], bem["results"][-2])}
        for r in rings:
            c = coarser.get(r["ring"], {}).get("ring_force_ratio")
            r["ring_force_ratio_change"] = (None if c is None or r["ring_force_ratio"] is None
                                            else r["ring_force_ratio"] - c)
    return rings


def ring_forces(result) -> dict[int, float]:
    """The force (N) on each lattice ring: the sum over its pillars."""
    out: dict[int, float] = {}
    for p in result.pillar_forces:
        k = lattice.ring(p.n, p.m)
        out[k] = out.get(k, 0.0) + p.force_N
    return out


def ring_studies(ladder: dict) -> dict[int, dict]:
    """The convergence study of each ring's force over a ladder's levels (a ring a level does
    not load carries 0 N there)."""
    per_level = [ring_forces(r) for r in ladder["results"]]
    h = [lv["h"] for lv in ladder["levels"]]
    rings = sorted(set().union(*per_level)) if per_level else []
    return {k: study(h, [f.get(k, 0.0) for f in per_level]) for k in rings}


def _differences(fem: dict, bem: dict) -> dict:
    """Per quantity: both models' estimates and bands, (FEM - BEM) / BEM, both bands over
    |BEM|, and whether the difference is beyond them."""
    out = {}
    for q in QUANTITIES:
        fv, fb, fhow = estimate(fem["studies"][q.key])
        bv, bb, bhow = estimate(bem["studies"][q.key])
        diff = (fv - bv) / bv if bv else None
        band = (fb + bb) / abs(bv) if bv else None
        out[q.key] = {
            "fem": fv, "fem_band": fb, "fem_how": fhow, "bem": bv, "bem_band": bb,
            "bem_how": bhow, "difference": diff, "band": band,
            "significant": bool(diff is not None and band is not None and abs(diff) > band)}
    return out


def _estimates(studies: dict, key, prefix: str, unit: str) -> dict:
    """``{prefix_unit, prefix_band_unit, prefix_how}`` of one study (None when absent)."""
    if key not in studies:
        return {f"{prefix}_{unit}": None, f"{prefix}_band_{unit}": None, f"{prefix}_how": None}
    v, b, how = estimate(studies[key])
    return {f"{prefix}_{unit}": v, f"{prefix}_band_{unit}": b, f"{prefix}_how": how}


def _ring_estimates(fem: dict, ladders: dict) -> list[dict]:
    """Each ring's force as the Richardson estimate of fem-3d and of each BEM ladder given."""
    studies = {"fem": ring_studies(fem)} | {k: ring_studies(v) for k, v in ladders.items()}
    rings = sorted(set().union(*(set(s) for s in studies.values())))
    return [{"ring": k, **{n: v for name, s in studies.items()
                           for n, v in _estimates(s, k, name, "N").items()}} for k in rings]


def _profile_estimates(fem: dict, ladders: dict, radius_m: float) -> list[dict]:
    """The centre pillar's top pressure at r = x radius, x in :data:`PROFILE_POINTS`, as each
    model's Richardson estimate (compare's profile sampling); points every model's levels
    cover."""
    studies = {"fem": profile_studies(fem, radius_m, PROFILE_POINTS)} | {
        k: profile_studies(v, radius_m, PROFILE_POINTS) for k, v in ladders.items()}
    out = []
    for x in PROFILE_POINTS:
        key = profile_key(x)
        if key not in studies["fem"]:
            continue
        out.append({"r_over_radius": x, "r_m": x * radius_m,
                    **{n: v for name, s in studies.items()
                       for n, v in _estimates(s, key, name, "Pa").items()}})
    return out


# --- targets of the elastic BEM -------------------------------------------------------------
def _group(checks: list[dict], target: float) -> dict:
    """Several checks of one target: met when every one is (None when one is not judged or
    there are none); ``worst`` the check with the largest |error| / allowed."""
    judged = [c for c in checks if c["error"] is not None]
    worst = max(judged, key=lambda c: abs(c["error"]) / c["allowed"], default=None)
    met = (None if not checks or any(c["met"] is None for c in checks)
           else all(c["met"] for c in checks))
    return {"target": target, "met": met, "checks": checks,
            "worst_error": None if worst is None else worst["error"],
            "worst_allowed": None if worst is None else worst["allowed"]}


def evaluate_targets(row: dict) -> dict:
    """The elastic BEM's targets on one row (its ``elastic_quantities``, ``ring_forces`` and
    ``profile``): F_T, sigma0, rings and profile, each with ``met``, and ``every`` (True only
    when each of the four is met)."""
    q = row.get("elastic_quantities") or {}
    out = {}
    for key in ("F_T", "sigma0"):
        d = q.get(key) or {}
        out[key] = judge(d.get("bem"), d.get("bem_band"), d.get("fem"), d.get("fem_band"),
                         TARGETS[key])
    out["rings"] = _group([{"ring": r["ring"], **judge(
        r.get("elastic_N"), r.get("elastic_band_N"), r.get("fem_N"), r.get("fem_band_N"),
        TARGETS["rings"])} for r in row.get("ring_forces") or []], TARGETS["rings"])
    out["profile"] = _group([{"r_over_radius": p["r_over_radius"], **judge(
        p.get("elastic_Pa"), p.get("elastic_band_Pa"), p.get("fem_Pa"), p.get("fem_band_Pa"),
        TARGETS["profile"])} for p in row.get("profile") or []], TARGETS["profile"])
    out["every"] = all(out[k]["met"] is True for k in TARGETS)
    return out


def targets_met(rows: list[dict]) -> dict:
    """How many scenes meet every target: ``{"scenes", "of", "text"}``."""
    n = sum(1 for r in rows if (r.get("targets") or {}).get("every"))
    return {"scenes": n, "of": len(rows),
            "text": f"{n} of {len(rows)} scenes meet every target of the elastic BEM"}


def compare_point(point: LatticePoint, fem_outcomes, bem_outcomes, elastic_outcomes=(),
                  dense_outcomes=(), rung_outcomes=()) -> dict:
    """One scene of the study: the three ladders, each BEM's differences beside the bands, the
    rings, the profile and the elastic BEM's targets."""
    fem = _ladder(fem_outcomes, "mesh_size", 1.0)
    bems = {HOOKE: _ladder(bem_outcomes, "cells_per_diameter", -1.0),
            ELASTIC: _ladder(elastic_outcomes, "cells_per_diameter", -1.0)}
    row = {"label": point.label, "title": point.title,
           "surface_fraction": point.surface_fraction, "ratio": point.ratio,
           "substrate": point.substrate, "substrate_E_Pa": point.substrate_E_Pa,
           "zeta_um": point.zeta_um, "fem_error": fem["error"],
           "bem_error": bems[HOOKE]["error"],
           "elastic_error": bems[ELASTIC]["error"], "quantities": {},
           "elastic_quantities": {}}
    failed = {name: ladder for name, ladder in
              ((FEM_MODEL, fem), (BEM_NAMES[HOOKE], bems[HOOKE]),
               (BEM_NAMES[ELASTIC], bems[ELASTIC])) if ladder["error"]}
    good = {k: v for k, v in bems.items() if not v["error"]} if not fem["error"] else {}
    if good:
        row["converged"] = all(r["converged"] for ladder in [fem, *good.values()]
                               for r in ladder["levels"])
        row["pillars_in_contact"] = {"fem": fem["results"][-1].pillars_in_contact} | {
            ("bem" if k == HOOKE else k): v["results"][-1].pillars_in_contact
            for k, v in good.items()}
        row["fem_levels"] = fem["levels"]
    if HOOKE in good:
        row["quantities"] = _differences(fem, good[HOOKE])
        row["rings"] = _rings(fem, good[HOOKE])
        row["bem_levels"] = good[HOOKE]["levels"]
    if ELASTIC in good:
        row["elastic_quantities"] = _differences(fem, good[ELASTIC])
        row["elastic_rings"] = _rings(fem, good[ELASTIC])
        row["elastic_levels"] = good[ELASTIC]["levels"]
    if dense_outcomes:
        row["elastic_dense_levels"] = _single_levels(dense_outcomes, "elements_per_diameter")
    if rung_outcomes:
        row["elastic_fft_rungs"] = _single_levels(rung_outcomes, "cells_per_diameter")
    if good:
        radius = point.scene().pillars.diameter_m / 2.0
        row["ring_forces"] = _ring_estimates(fem, good)
        row["profile"] = _profile_estimates(fem, good, radius)
    row["targets"] = evaluate_targets(row)
    if failed:
        row["status"] = "failed: " + "; ".join(f"{name}: {ladder['error']}"
                                               for name, ladder in failed.items())
        row["exit"] = max(ladder["exit"] for ladder in failed.values())
    else:
        row["status"] = "ok" if row["converged"] else "not converged"
    return row
