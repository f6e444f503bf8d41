"""The refinement ladders the studies share: the cases of N levels of one model and their
verification study (observed order, Richardson estimate, GCI), the estimate a comparison
reads from a study, the pillar-top profile's studies, and the reference cross-checked
between several models' Richardson estimates."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, TypedDict

from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import InputError, Scene

from ..analysis.profiles import profile_at
from ..analysis.verification import gci_three, gci_two, study
from ..engine import Case, Outcome
from ..registry import (FLOOR_QUANTITIES, MODELS, QUANTITIES, check_option, flag, get_model,
                        ladder_for, quantity_values)

LEVELS_RANGE = (2, 8)


class LadderInfo(TypedDict):
    """How the studied model was refined: its refined option, what h means, h's power of
    the option's value, the options every level shares."""
    option: str
    h_meaning: str
    h_power: float
    fixed: dict[str, Any]


class LadderStudy(TypedDict):
    """:func:`study_levels`' result, as compare, gecit, the pytest plugin,
    :mod:`validation.testing` and the convergence plot read it (JSON-ready but ``results``).

    ``levels``: one row per level, coarse to fine: ``level``, ``options``, ``value`` (the
    refined option's), ``h``, ``cached``, ``converged``, ``message``, ``wall_time_s``, ``vtu``
    and every quantity of :func:`validation.registry.quantity_values` by key (SI).
    ``studies``: per quantity key, :func:`validation.analysis.verification.study`'s dict."""
    model: str
    label: str
    scene: dict[str, Any]
    ladder: LadderInfo
    levels: list[dict[str, Any]]
    studies: dict[str, dict[str, Any]]
    all_converged: bool
    results: list[ContactResult]


class Estimate(TypedDict):
    """A Richardson estimate: the extrapolated value, the order, the band (absolute, SI) and
    the cell sizes h it came from."""
    f_exact: float | None
    order: float | None
    band: float | None
    sizes: list[float]


class ModelEstimate(Estimate):
    """One model's estimates of one quantity: the observed order's, with its GCI status, its
    asymptotic ratio and why it looks pre-asymptotic (empty when it does not), and the one at
    the model's expected order (``assumed``; None without one)."""
    status: str
    asymptotic_ratio: float | None
    pre_asymptotic: list[str]
    assumed: Estimate | None


class Reference(TypedDict):
    """:func:`reference_values`' reference of one quantity, as calibrate, validate-plan and
    the tradeoff's tables read it: ``value`` (SI), the model(s) it came from, its order and
    band (None without a Richardson estimate), the sizes, how it was chosen (``status``,
    ``basis``), whether it is pre-asymptotic, the flags raised and every model's estimate."""
    value: float
    model: str | None
    order: float | None
    band: float | None
    sizes: list[float]
    status: str
    basis: str | None
    pre_asymptotic: bool | None
    flags: list[str]
    per_model: dict[str, ModelEstimate]


def check_ladder(model: str, levels: int, coarsest: float | None = None,
                 levels_flag: str = "--levels", lo: int = LEVELS_RANGE[0]) -> list:
    """The option values of ``levels`` refinements of ``model`` from ``coarsest`` (default:
    the ladder's), coarse to fine; InputError (one line) unless every level is allowed."""
    ladder = ladder_for(model)
    hi = LEVELS_RANGE[1]
    if isinstance(levels, bool) or not isinstance(levels, int) or not lo <= levels <= hi:
        raise InputError(f"{levels_flag} {levels!r}: allowed range is [{lo}, {hi}]")
    name = flag(ladder.option)
    spec = get_model(model).options[ladder.option]
    if coarsest is not None:
        check_option(ladder.option, coarsest, spec=spec)
    values = [ladder.value(k, coarsest) for k in range(levels)]
    for k, value in enumerate(values):
        try:
            check_option(ladder.option, value, spec=spec)
        except InputError:
            start = f"{name} {coarsest:g}" if coarsest is not None else \
                f"{model}'s default {name} {ladder.coarsest:g}"
            raise InputError(
                f"{start} with {levels_flag} {levels}: level {k + 1} would be "
                f"{ladder.option} = {value:g}, outside {spec.allowed()} "
                f"(fewer levels, or another coarsest level)") from None
    return values


def level_cases(model: str, scene: Scene, levels: int, *, coarsest: float | None = None,
                tag: str = "", vtu_finest: bool = False,
                options: dict | None = None) -> list[Case]:
    """The cases of ``levels`` refinements of ``model`` on ``scene``, coarse to fine;
    ``options``: the model's other options, the same on every level (``pillars``, say)."""
    check_ladder(model, levels, coarsest)
    ladder = ladder_for(model)
    return [Case(model, scene, {**ladder.options(k, coarsest), **(options or {})},
                 vtu=vtu_finest and k == levels - 1,
                 tag=f"{tag + ' ' if tag else ''}{k + 1}/{levels}") for k in range(levels)]


def study_levels(model: str, scene: Scene, outcomes: list[Outcome]) -> LadderStudy:
    """The verification study of finished levels (coarse to fine).

    Returns a JSON-ready dict with the ladder, one row per level and, per quantity, the
    :func:`validation.analysis.verification.study` dict, ``label`` (the model with its pillar
    model, as tables and plots name it), plus ``results`` (the ContactResults, not JSON).  A
    level that failed raises its error.
    """
    ladder = ladder_for(model)
    rows: list[dict[str, Any]] = []
    results: list[ContactResult] = []
    for k, o in enumerate(outcomes):
        result = o.unwrap()
        value = o.case.options[ladder.option]
        vtu = o.files.get("fields.vtu")
        rows.append({"level": k, "options": dict(o.case.options), "value": value,
                     "h": ladder.size(value), "cached": o.cached,
                     "converged": bool(result.converged),
                     "message": str(result.diagnostics.get("message", "")),
                     "wall_time_s": o.timing["wall_time_s"],
                     "vtu": None if vtu is None else str(vtu), **quantity_values(result)})
        results.append(result)
    h = [r["h"] for r in rows]
    mixed = any(r.floor_force_N > 0.0 for r in results)  # the floor's quantities too
    studies = {q.key: study(h, [r[q.key] for r in rows])
               for q in QUANTITIES + (FLOOR_QUANTITIES if mixed else ())}
    return {"model": model, "label": results[-1].label if results else model,
            "scene": scene.to_dict(),
            "ladder": {"option": ladder.option, "h_meaning": ladder.h_meaning,
                       "h_power": ladder.h_power, "fixed": ladder.fixed},
            "levels": rows, "studies": studies,
            "all_converged": all(r["converged"] for r in rows), "results": results}


def estimate(st: dict) -> tuple[float, float, str]:
    """(value, band, how): the Richardson estimate and its GCI band when the finest levels
    are asymptotic; otherwise the finest value with the fallback band (3 x the spread)."""
    g = st["gci"]
    if g["status"] == "ok" and g["f_exact"] is not None:
        return g["f_exact"], g["uncertainty"], "richardson"
    return g["f"][0], g["fallback_uncertainty"], g["status"]


def profile_key(x: float) -> str:
    """The name of the profile sample at r = x r_ref: ``sigma(r=0.5)``."""
    return f"sigma(r={x:g})"


def profile_studies(data: dict, r_ref: float, points) -> dict:
    """The convergence study of the pillar-top pressure at r = x r_ref for each x in
    ``points``, over a ladder's ``levels`` (each with its ``h``) and ``results``; a point
    outside any level's profile is left out."""
    h = [lv["h"] for lv in data["levels"]]
    samples = [profile_at(res.pillar_top_profile, r_ref, points) for res in data["results"]]
    out = {}
    for i, x in enumerate(points):
        f = [s[i] for s in samples]
        if all(v is not None for v in f) and len(f) >= 2:
            out[profile_key(x)] = study(h, f)
    return out


# An observed order further than ORDER_TOL from a model's expected order (its declaration's
# ``expected_order``, in its ladder's cell size h), or an asymptotic ratio
# GCI23 / (r^p GCI12) further than ASYMPTOTIC_RATIO_TOL from 1, marks the estimate as
# pre-asymptotic.
ORDER_TOL = 0.3
ASYMPTOTIC_RATIO_TOL = 0.25


def _model_estimate(rows: list, short: str, model: str) -> ModelEstimate | None:
    """The Richardson estimates of one model from its finest converged rungs: the observed
    order's over three (``f_exact``, ``order``, ``band``, ``status``, and the reasons it is
    pre-asymptotic, empty when it looks asymptotic) and, for a model with an expected order,
    the two finest extrapolated at that order (``assumed``: Roache's two-grid GCI, Fs = 3).
    None below three rungs."""
    mine = sorted((r for r in rows if r["model"] == model and r["converged"]),
                  key=lambda r: r["h"])
    if len(mine) < 3:
        return None
    h, f = [r["h"] for r in mine[:3]], [r[short] for r in mine[:3]]
    g = gci_three(h, f)
    est: ModelEstimate = {"f_exact": g.f_exact, "order": g.order, "band": g.uncertainty,
                          "status": g.status, "asymptotic_ratio": g.asymptotic_ratio,
                          "sizes": g.h, "pre_asymptotic": [], "assumed": None}
    expected = MODELS[model].expected_order if model in MODELS else None
    if expected is not None and f[0] != f[1]:
        a = gci_two(h[:2], f[:2], expected)
        if a.f_exact is not None:
            est["assumed"] = {"f_exact": a.f_exact, "order": expected, "band": a.uncertainty,
                              "sizes": a.h}
    if g.status != "ok" or g.uncertainty is None:
        return est
    if expected is not None and abs(g.order - expected) > ORDER_TOL:
        est["pre_asymptotic"].append(f"observed order {g.order:.2f}, expected {expected:g}")
    if g.asymptotic_ratio is not None and \
            abs(g.asymptotic_ratio - 1.0) > ASYMPTOTIC_RATIO_TOL:
        est["pre_asymptotic"].append(f"GCI23 / (r^p GCI12) = {g.asymptotic_ratio:.2f}")
    return est


def _tiers(per_model: dict[str, ModelEstimate]) -> tuple[dict[str, Estimate], ...]:
    """The models' estimates in order of trust: observed-order estimates that look
    asymptotic; for models whose observed order is pre-asymptotic or unobservable (or
    oscillating), the estimate at their expected order; observed-order estimates that are
    pre-asymptotic and have no expected order."""
    asymptotic: dict[str, Estimate] = {}
    assumed: dict[str, Estimate] = {}
    pre: dict[str, Estimate] = {}
    for m, e in per_model.items():
        observed = e["status"] == "ok" and e["band"] is not None
        if observed and not e["pre_asymptotic"]:
            asymptotic[m] = e
        elif e["assumed"] is not None:
            assumed[m] = e["assumed"]
        elif observed:
            pre[m] = e
    return asymptotic, assumed, pre


def _disagreements(estimates: Mapping[str, Estimate]) -> list[str]:
    """Pairs of estimates further apart than their bands combined in quadrature (independent
    uncertainties; the test ``compare`` applies to BEM against FEM)."""
    flags, names = [], sorted(estimates)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            ea, eb = estimates[a], estimates[b]
            gap = abs(ea["f_exact"] - eb["f_exact"])
            if gap > math.hypot(ea["band"], eb["band"]):
                flags.append(f"{a} ({ea['f_exact']:.7g} +- {ea['band']:.2g}) and {b} "
                             f"({eb['f_exact']:.7g} +- {eb['band']:.2g}) disagree beyond "
                             "their bands")
    return flags


def reference_values(rows: list) -> dict[str, Reference]:
    """Per quantity: a reference cross-checked between the models' Richardson estimates.

    Each model with three converged rungs gives an estimate (observed order, Richardson value,
    GCI band).  An estimate whose order is far from the model's expected one
    (its declaration's ``expected_order``) or whose asymptotic ratio is far from 1 is
    pre-asymptotic and
    not preferred: such a model (or one whose order cannot be observed) enters at its expected
    order instead, from its two finest rungs with the two-grid band (Fs = 3), after every
    asymptotic estimate (:func:`_tiers`).  Among the estimates of the most trusted tier
    present: if they agree (every pair closer than its bands combined in quadrature), the
    narrowest is the reference; if not, the disagreement is flagged and the reference is the
    middle of the union of their bands, with a band that covers it.  Every pre-asymptotic
    estimate and every disagreement between the models' estimates is flagged.  Without any
    estimate, the most expensive converged solution stands in (no band).
    """
    out: dict[str, Reference] = {}
    models = sorted({r["model"] for r in rows})
    tier_names = ("asymptotic", "expected order", "pre-asymptotic")
    for short in (q.key for q in QUANTITIES):
        per_model: dict[str, ModelEstimate] = {}
        for m in models:
            est = _model_estimate(rows, short, m)
            if est is not None:
                per_model[m] = est
        tiers = _tiers(per_model)
        flags = [f"{m}: pre-asymptotic ({'; '.join(e['pre_asymptotic'])})"
                 for m, e in per_model.items() if e["pre_asymptotic"]]
        observed = {m: e for m, e in per_model.items()
                    if e["status"] == "ok" and e["band"] is not None}
        everyone = {m: e for tier in tiers for m, e in tier.items()}
        for text in _disagreements(observed) + _disagreements(everyone):
            if text not in flags:
                flags.append(text)
        level = next((k for k, tier in enumerate(tiers) if tier), None)
        # Every model's own extrapolation (per_model): do the models converge to the same
        # answer?  The keys keep the order the reports have always printed.
        ref: Reference
        if level is not None:
            pool = tiers[level]
            tier = f" ({tier_names[level]})"
            if not _disagreements(pool):
                m = min(pool, key=lambda k: pool[k]["band"])
                e = pool[m]
                ref = {"value": e["f_exact"], "model": m, "order": e["order"],
                       "band": e["band"], "sizes": e["sizes"], "status": "richardson",
                       "basis": "the narrowest of agreeing estimates" + tier,
                       "pre_asymptotic": level > 0, "flags": flags, "per_model": per_model}
            else:
                lo = min(e["f_exact"] - e["band"] for e in pool.values())
                hi = max(e["f_exact"] + e["band"] for e in pool.values())
                ref = {"value": 0.5 * (lo + hi), "model": "+".join(sorted(pool)),
                       "order": None, "band": 0.5 * (hi - lo), "sizes": [],
                       "status": "richardson",
                       "basis": "the union of disagreeing estimates' bands" + tier,
                       "pre_asymptotic": level > 0, "flags": flags, "per_model": per_model}
        else:
            # Sizes h of different models are in different units: take the most expensive
            # converged solution, a unit-free stand-in for the most resolved one.
            done = [r for r in rows if r["converged"]]
            finest = max(done, key=lambda r: r.get("wall_time_s", 0.0)) if done else None
            ref = {"value": finest[short] if finest else 0.0,
                   "model": finest["model"] if finest else None, "order": None,
                   "band": None, "status": "most expensive solution (no Richardson estimate)",
                   "sizes": [finest["h"]] if finest else [], "basis": None,
                   "pre_asymptotic": None, "flags": flags, "per_model": per_model}
        out[short] = ref
    return out
