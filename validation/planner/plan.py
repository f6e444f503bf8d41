"""The planner: which model a scene needs for a given accuracy, and what it will cost.

For every candidate (a model at one option value, or a closed form; listed in the data) the
planner predicts, per requested quantity,

- the discretisation error: the candidate's error measured on calibration scenes against a
  converged reference of the same physics, interpolated at this scene's features;
- the model error: each measured error of the candidate's physics against a more complete
  one (Hooke pillar against elastic pillar, flat punch against curved lens, Hertz against
  the lattice, finite blocks against half-spaces), interpolated likewise;

and adds them with their leave-one-out margins (:mod:`.tables`), with their signs where
both have a systematic sign (:func:`combined_error`: a coarse BEM's sigma0 high, the Hooke
pillar's low, so they partly cancel); its time and memory
come from the cost fits (:mod:`.costs`), their seconds carried to this machine and thread
count by its calibration (:mod:`.machine`). The choice is the cheapest candidate
predicted within tolerance for every requested quantity.

A candidate's ``physics`` drops the model-error components it does not carry
(:data:`REMOVED_BY`): the elastic-pillar candidates (the BEMs with ``pillars = elastic``,
fem-3d) carry no Hooke error (the Hooke pillar's sigma0 in a lattice: 3-60 %, measured by
the lattice study against fem-3d).  On lattices each elastic BEM rung carries its whole
error against fem-3d, measured by the lattice studies (one discretisation table per rung,
read before the same rung's Hooke table: :meth:`.tables.PlannerData.tables_for`); on one
pillar it carries the Hooke BEM's discretisation at that rung plus a hand bound on its
coupling; fem-3d carries its discretisation alone.  The hand entries of the data (the
elastic BEMs' and fem-3d's candidacy and costs, the one-pillar bound) give their sources in
their ``note``.  The elastic BEM's time includes the pillar compliance's one-off build
unless it is cached (:data:`.costs.SETUPS`).

When the model error that every available candidate carries exceeds the tolerance, none is
within tolerance: the plan says so and takes the cheapest candidate within tolerance of
that unavoidable error.  A candidate that would not fit in memory (``memory_short``), or
exceeds ``budget`` seconds, is left out with the reason; when the budget leaves none, the
plan has no choice and its reason names the budget and the cheapest candidate's time.
"""

from __future__ import annotations

import math

from pillar_xval.outcome.memory import memory_short
from pillar_xval.scenes import InputError, Scene, ScopeError, analytic
from pillar_xval.threads import thread_count

from ..registry import QUANTITIES, get_model
from . import machine
from .features import features, regime
from .tables import PlannerData, load_data, machine_data
from ..output.formatting import percent

__all__ = ["DEFAULT_QUANTITIES", "DEFAULT_TOLERANCE", "check_request", "combined_error",
           "default_data", "hooke_error", "hooke_note", "plan", "plan_text", "solve_auto"]

DEFAULT_TOLERANCE = 0.01
DEFAULT_QUANTITIES = ("F_T", "sigma0")
# Model-error components a candidate's physics does not carry: the elastic-pillar models
# (bem/bem-fft with pillars = elastic, fem-3d) have no Hooke pillar (their own, smaller model
# error is a table of theirs, e.g. the elastic BEM's coupling through the half-space).
REMOVED_BY = {"elastic-pillar": ("hooke",)}
# "Closest" when nothing is within tolerance of the unavoidable error: candidates whose worst
# error is within this factor of the smallest worst error count as equally close.
CLOSEST_SLACK = 1.1

# The shipped data carried to this machine, per (mode, thread count).
_DATA: dict = {}


def default_data() -> PlannerData:
    """The shipped error and cost models, their seconds carried to this machine at
    :func:`pillar_xval.threads.thread_count` threads (:mod:`.machine`; its calibration runs
    once per machine and thread count, a few seconds, then comes from its cache)."""
    key = (machine.mode(), thread_count())
    if key not in _DATA:
        _DATA[key] = machine_data(load_data(), machine.seconds_here())
    return _DATA[key]


def _data(data: PlannerData | None) -> PlannerData:
    return default_data() if data is None else data


def check_request(tolerance=DEFAULT_TOLERANCE, quantities=DEFAULT_QUANTITIES,
                  budget=None) -> tuple[float, tuple, float | None]:
    """Validated (tolerance, quantities, budget); InputError naming the option otherwise.
    ``quantities`` is a comma list or a sequence of names; an empty entry (``F_T,,sigma0``)
    or an empty list is refused, not dropped."""
    known = [q.key for q in QUANTITIES]
    tolerance = DEFAULT_TOLERANCE if tolerance is None else tolerance
    quantities = DEFAULT_QUANTITIES if quantities is None else quantities
    given = quantities if isinstance(quantities, str) else \
        ",".join(map(str, quantities)) if isinstance(quantities, (list, tuple)) else quantities
    names = ([q.strip() for q in quantities.split(",")] if isinstance(quantities, str)
             else list(quantities) if isinstance(quantities, (list, tuple)) else None)
    if not names or any(not isinstance(q, str) or not q for q in names):
        raise InputError(f"--quantities {given!r}: expected one or more of "
                         f"{', '.join(known)}, comma-separated, none empty")
    quantities = tuple(dict.fromkeys(names))
    bad = [q for q in quantities if q not in known]
    if bad:
        raise InputError(f"--quantities {','.join(map(str, bad))}: unknown; allowed: "
                         f"{', '.join(known)} (comma-separated)")
    try:
        tolerance = float(tolerance)
    except (TypeError, ValueError):
        raise InputError(f"--tolerance {tolerance!r}: expected a number") from None
    if not (math.isfinite(tolerance) and 0.0 < tolerance <= 1.0):
        raise InputError(f"--tolerance {tolerance!r}: allowed range is (0, 1] (a relative "
                         "error: 0.01 is 1 %)")
    if budget is not None:
        try:
            budget = float(budget)
        except (TypeError, ValueError):
            raise InputError(f"--budget {budget!r}: expected a number of seconds > 0") from None
        if not (math.isfinite(budget) and budget > 0):
            raise InputError(f"--budget {budget!r}: must be a number of seconds > 0")
    return tolerance, quantities, budget


def combined_error(disc: float, factor: float, disc_sign: int, model: list) -> float | None:
    """The bound on a discretisation error and model errors added with their signs, or None
    where one of them has no systematic sign (:meth:`.tables.ErrorTable.sign`).

    ``disc`` is the interpolated discretisation error's magnitude and ``factor`` its margin:
    the error is ``disc_sign`` times a magnitude within [disc / factor, disc * factor].
    ``model`` lists (value, margin, sign) per model component: its signed error lies within
    value +- margin.  The bound is the largest |discretisation + model| over that box, found
    at a corner (|.| is convex).  Where the signs agree it is the plain sum of the bounds; where
    they differ the errors partly cancel and it is less."""
    if not disc_sign or not model or not all(sign for _, _, sign in model):
        return None
    value = sum(v for v, _, _ in model)
    margin = sum(m for _, m, _ in model)
    return max(abs(disc_sign * d + value + e)
               for d in (disc / factor, disc * factor) for e in (-margin, margin))


def _candidate(scene, x, reg, cand, data, quantities) -> dict:
    """Predictions for one candidate: errors per quantity, time, memory, eligibility."""
    model, options = cand["model"], dict(cand.get("options", {}))
    physics = cand.get("physics", "")
    out = {"label": cand.get("label", model), "model": model, "options": options,
           "physics": physics, "errors": {}, "time_s": None, "setup_s": 0.0,
           "memory_MB": None, "eligible": False, "why": ""}
    if reg["name"] == "mixed":
        # Only a model with the floor; its errors are read from the tables of the tops'
        # regime (the floor's own quantities are not in the tables; README, "The floor").
        if not get_model(model).floor:
            out["why"] = "does not include the floor between the pillars, which the lens reaches"
            return out
        reg = dict(reg, name="multi")
    if reg["name"] not in cand.get("regimes", ()):
        out["why"] = cand.get("scope", f"not for {reg['label']} scenes")
        return out
    disc = [] if cand.get("closed_form") else data.tables_for(model, options, reg["name"],
                                                              "discretisation")
    if not cand.get("closed_form") and not disc:
        out["why"] = f"no measured convergence for {reg['name']} scenes"
        return out
    removed = REMOVED_BY.get(physics, ())
    components = [t for t in data.tables_for(model, options, reg["name"], "model")
                  if t.component not in removed]
    scale = float(data.policy["margin_scale"])
    sign_share = float(data.policy["sign_share"])
    extrapolated = set()
    for q in quantities:
        parts, model_errors = {}, []
        if disc:
            pred = disc[0].predict(x, q)
            if pred is None:
                out["why"] = f"no measured convergence of {q} for {reg['name']} scenes"
                return out
            factor = disc[0].margin(q, x, scale)
            parts["discretisation"] = pred[0] * factor
            magnitude, disc_sign = pred[0], disc[0].sign(q, sign_share)
            if pred[1]:
                extrapolated.add(f"discretisation ({', '.join(disc[0].features)})")
        for t in components:
            pred = t.predict(x, q)
            if pred is None:
                continue
            margin = t.margin(q, x, scale)
            parts[t.component] = parts.get(t.component, 0.0) + abs(pred[0]) + margin
            model_errors.append((pred[0], margin, t.sign(q, sign_share)))
            if pred[1]:
                extrapolated.add(f"{t.component} ({', '.join(t.features)})")
        model_part = sum(v for k, v in parts.items() if k != "discretisation")
        if cand.get("closed_form") and not parts:
            out["why"] = f"error of {q} not measured for {reg['name']} scenes"
            return out
        total = parts.get("discretisation", 0.0) + model_part
        both = combined_error(magnitude, factor, disc_sign, model_errors) if disc else None
        out["errors"][q] = {"total": total if both is None else min(total, both),
                            "model": model_part, "parts": parts,
                            "signed": bool(both is not None and both < total)}
    out["extrapolated"] = sorted(extrapolated)
    fit = data.costs.get(cand.get("cost", model))
    if fit is None:
        out["why"] = "no cost measurement"
        return out
    try:
        time_s, memory = fit.predict(scene, options, reg["name"])
        out["setup_s"] = fit.setup_time(scene)
    except (InputError, ValueError) as exc:
        out["why"] = f"refused: {' '.join(str(exc).split())}"
        return out
    out["time_s"], out["memory_MB"] = time_s, memory / 2**20
    short = memory_short(memory)
    if short is not None:
        out["why"] = f"refused: needs ~{memory / 2**30:.3g} GiB, {short}"
        return out
    out["eligible"] = True
    return out


def plan(scene: Scene, tolerance: float = DEFAULT_TOLERANCE, quantities=DEFAULT_QUANTITIES,
         budget: float | None = None, data: PlannerData | None = None,
         progress=None) -> dict:
    """The plan for ``scene``: regime, every candidate's predicted errors, time and memory,
    and the choice with its reason (JSON-ready).

    Parameters
    ----------
    scene : Scene
    tolerance : float
        Relative error allowed on every requested quantity (0.01 = 1 %).
    quantities : sequence of str or str
        Among F_T, sigma0, a, A (comma-separated string accepted).
    budget : float, optional
        Wall time (s) a candidate may take at most.
    data : PlannerData, optional
        Error and cost models (default: the shipped ones, carried to this machine:
        :func:`default_data`).
    progress : callable, optional
        ``progress(text)`` hears of each step (reading the data, each candidate): a plan's
        first call reads the tables and imports the FEMs' memory estimates (seconds on a
        cold start).
    """
    tolerance, quantities, budget = check_request(tolerance, quantities, budget)
    say = progress or (lambda text: None)
    say("reading the planner's error and cost tables (and, once per machine and thread "
        "count, timing this machine: a few seconds)")
    data = _data(data)
    given = scene
    scene = planning_scene(scene)
    reg = regime(scene)
    x = features(scene, reg)
    cands = []
    for k, c in enumerate(data.candidates):
        say(f"predicting candidate {k + 1} of {len(data.candidates)}: "
            f"{c.get('label', c.get('model'))}")
        cands.append(_candidate(scene, x, reg, c, data, quantities))
    over_budget = []
    for c in cands:
        if c["eligible"] and budget is not None and c["time_s"] > budget:
            c["eligible"], c["why"] = False, f"predicted {c['time_s']:.3g} s > budget {budget:g} s"
            over_budget.append(c)
    eligible = [c for c in cands if c["eligible"]]
    choice, within, reason, floor = None, False, "", {}
    if eligible:
        floor = {q: min(c["errors"][q]["model"] for c in eligible) for q in quantities}
        ok = [c for c in eligible if _worst(c, quantities, tolerance) <= 1.0]
        if ok:
            choice, within = min(ok, key=lambda c: c["time_s"]), True
            reason = (f"{choice['label']} is the cheapest model predicted within "
                      f"{_pct(tolerance)} for {', '.join(quantities)} "
                      f"({_errors_text(choice, quantities)}; ~{_time_text(choice['time_s'])})")
        else:
            short = [q for q in quantities if floor[q] > tolerance]
            near = [c for c in eligible
                    if all(c["errors"][q]["total"] <= floor[q] + tolerance for q in quantities)]
            if near:
                choice = min(near, key=lambda c: c["time_s"])
                why_none = "; ".join(
                    f"{q}: every available model carries >= {_pct(floor[q])} of model error"
                    f" ({_main_component(eligible, q)})" for q in short) or \
                    "no candidate's discretisation reaches it"
                reason = (f"none is predicted within {_pct(tolerance)} ({why_none}); "
                          f"{choice['label']} is the cheapest within {_pct(tolerance)} of "
                          f"that unavoidable error ({_errors_text(choice, quantities)}; "
                          f"~{_time_text(choice['time_s'])})")
                if any(_main_component(eligible, q) in REMOVED_BY["elastic-pillar"]
                       for q in short):
                    reason += _elastic_left_out(cands)
            else:
                worst = {id(c): max(c["errors"][q]["total"] for q in quantities)
                         for c in eligible}
                best = min(worst.values())
                close = [c for c in eligible if worst[id(c)] <= CLOSEST_SLACK * best]
                choice = min(close, key=lambda c: c["time_s"])
                reason = (f"none is predicted within {_pct(tolerance)}; {choice['label']} "
                          f"comes closest ({_errors_text(choice, quantities)}; "
                          f"~{_time_text(choice['time_s'])})")
    elif over_budget:
        cheapest = min(over_budget, key=lambda c: c["time_s"])
        reason = (f"--budget {budget:g}: no candidate is predicted within {budget:g} s; the "
                  f"cheapest, {cheapest['label']}, is predicted to take "
                  f"{_time_text(cheapest['time_s'])}")
    else:
        reason = "no candidate can run this scene: " + "; ".join(
            f"{c['label']}: {c['why']}" for c in cands)
    return {"scene": given.to_dict(), "load_control": given.load_control,
            "indentation_m": scene.indentation_m, "regime": reg, "features": x,
            "tolerance": tolerance,
            "quantities": list(quantities), "budget_s": budget, "candidates": cands,
            "unavoidable_error": floor,
            "choice": None if choice is None else {
                "label": choice["label"], "model": choice["model"],
                "options": choice["options"], "within_tolerance": within,
                "predicted_errors": {q: choice["errors"][q]["total"] for q in quantities},
                "time_s": choice["time_s"], "memory_MB": choice["memory_MB"]},
            "reason": reason, "data": data.provenance, "machine": _machine_note(data)}


def _machine_note(data: PlannerData) -> dict | None:
    """How the predicted seconds were carried to this machine: its thread count and each
    model's speed factor (time here over time where its fit was measured); None when they
    are the fits' own."""
    factors = {k: fit.speed for k, fit in data.costs.items()
               if getattr(fit, "here", None) is not None and hasattr(fit, "workload")}
    if not factors:
        return None
    return {"threads": thread_count(), "speed": factors}


def planning_scene(scene: Scene) -> Scene:
    """The scene the plan reads its regime, features, times and memory on: ``scene`` itself
    under a given indentation; under a given force, the scene at the indentation estimated
    for it (:func:`pillar_xval.scenes.analytic.indentation_estimate`, within 0.96-1.3 of the
    models' own on the paper's family), since every table is measured against indentation."""
    if scene.force_N is None:
        return scene
    return scene.designed(analytic.indentation_estimate(scene))


def hooke_error(scene: Scene, quantity: str = "sigma0", data: PlannerData | None = None,
                reg: dict | None = None, x: dict | None = None) -> float | None:
    """The Hooke pillar's model error of ``quantity`` on ``scene`` as the planner counts it
    for a Hooke-pillar candidate: the ``hooke`` part of that candidate's predicted error
    (|interpolated error| + its leave-one-out margin, :func:`_candidate`), the same number
    ``plan`` adds to the Hooke BEM's error.  The first candidate of the data that carries a
    ``hooke`` table for the scene's regime stands for all of them (those tables apply to a
    model whatever its resolution).  None where no ``hooke`` table covers the scene (a flat
    scene has no pillars)."""
    data = _data(data)
    reg = reg or regime(scene)
    x = x or features(scene, reg)
    for cand in data.candidates:
        if cand.get("closed_form") or "hooke" in REMOVED_BY.get(cand.get("physics", ""), ()) \
                or reg["name"] not in cand.get("regimes", ()):
            continue
        c = _candidate(scene, x, reg, cand, data, (quantity,))
        part = c["errors"].get(quantity, {}).get("parts", {}).get("hooke")
        if part is not None:
            return part
    return None


def hooke_note(scene: Scene) -> str | None:
    """The line a Hooke-pillar result carries on ``scene``: the planner's expected sigma0
    error of the Hooke pillar there (:func:`hooke_error`) and the flag that removes it; None
    on a flat scene."""
    if scene.is_flat:
        return None
    try:
        error = hooke_error(scene, "sigma0")
    except InputError as exc:  # damaged planner data: the solve stands, the number is missing
        return f"Hooke pillars: no expected error (the planner's data: {exc}); " \
               "--pillars elastic removes the Hooke spring's model error"
    if error is None:
        return None
    return (f"Hooke pillars: the planner expects sigma0 off by up to {100 * error:.2g} % on "
            "this scene (the Hooke spring's model error against the elastic pillar); "
            "--pillars elastic removes it")


def _elastic_left_out(cands: list) -> str:
    """Why the elastic-pillar candidates, which carry no Hooke error, were not taken."""
    elastic = [c for c in cands if c["physics"] == "elastic-pillar"]
    if not elastic:
        return "; no elastic-pillar model is a candidate (fem-3d, `--pillars elastic`)"
    why = sorted({c["why"] for c in elastic if not c["eligible"] and c["why"]})
    return ("; the elastic-pillar models remove the Hooke error"
            + (f" but are left out here ({'; '.join(why[:3])})" if why else ""))


def _worst(c: dict, quantities, tolerance: float) -> float:
    return max(c["errors"][q]["total"] for q in quantities) / tolerance


def _main_component(cands: list, q: str) -> str:
    best = min(cands, key=lambda c: c["errors"][q]["model"])
    parts = {k: v for k, v in best["errors"][q]["parts"].items() if k != "discretisation"}
    return max(parts, key=parts.get) if parts else "model"


def _pct(x: float) -> str:
    return percent(x, ".2g")


def _time_text(t: float) -> str:
    return f"{t:.2g} s" if t >= 0.01 else "< 0.01 s"


def _errors_text(c: dict, quantities) -> str:
    return ", ".join(f"{q} {_pct(c['errors'][q]['total'])}" for q in quantities)


def plan_text(p: dict) -> str:
    """The plan as a readable table."""
    reg = p["regime"]
    qs = p["quantities"]
    load = p["scene"]["load"]
    lines = [f"scene     {p['scene'].get('name', '?')}"
             + (f"  (F = {load['force_N'] * 1e6:.4g} uN: planned at its estimated indentation"
                f" {p['indentation_m'] * 1e6:.3g} um)" if "force_N" in load else ""),
             f"regime    {reg['label']}: {reg['why']}",
             f"request   {', '.join(qs)} within {_pct(p['tolerance'])}"
             + (f", at most {p['budget_s']:g} s" if p["budget_s"] else ""), "",
             f"{'candidate':<22}{'time':>9}{'memory':>9}"
             + "".join(f"{'err ' + q:>11}" for q in qs) + "  note"]
    for c in p["candidates"]:
        t = "-" if c["time_s"] is None else _time_text(c["time_s"])
        m = "-" if c["memory_MB"] is None else f"{c['memory_MB']:.0f} MB"
        errs = "".join(f"{_pct(c['errors'][q]['total']) if q in c['errors'] else '-':>11}"
                       for q in qs)
        mark = "<- chosen" if p["choice"] and c["label"] == p["choice"]["label"] else ""
        note = mark or (c["why"] if not c["eligible"] else "")
        if c["eligible"] and any(v.get("signed") for v in c["errors"].values()):
            note = (note + " " if note else "") + "(errors added with their signs)"
        if c.get("extrapolated") and c["eligible"]:
            note = (note + " " if note else "") + "(extrapolated)"
        if c.get("setup_s") and c["time_s"] is not None:
            note = (note + " " if note else "") + \
                f"(incl. {_time_text(c['setup_s'])} one-off set-up: not cached)"
        lines.append(f"{c['label']:<22}{t:>9}{m:>9}{errs}  {note}")
    lines += ["", f"choice    {p['choice']['label'] if p['choice'] else 'none'}",
              f"reason    {p['reason']}"]
    m = p.get("machine")
    lines.append("times     " + (
        "the fits' own seconds (PILLAR_XVAL_MACHINE=reference, or no calibration)" if not m
        else f"this machine's at {m['threads']} thread(s): each model's fitted time times "
             + ", ".join(f"{k} {v:.2g}" for k, v in sorted(m["speed"].items()))))
    return "\n".join(lines)


def compact(p: dict) -> dict:
    """The plan without the per-candidate details (what a result records)."""
    return {"regime": p["regime"]["label"], "tolerance": p["tolerance"],
            "quantities": p["quantities"], "choice": p["choice"], "reason": p["reason"],
            "unavoidable_error": p["unavoidable_error"],
            "candidates": [{"label": c["label"], "eligible": c["eligible"],
                            "time_s": c["time_s"],
                            "errors": {q: v["total"] for q, v in c["errors"].items()}}
                           for c in p["candidates"]]}


# Under a force: solves of successive choices before the plan settles (module docstring).
MAX_FORCE_PLANS = 4


def solve_auto(scene: Scene, tolerance: float = DEFAULT_TOLERANCE,
               quantities=DEFAULT_QUANTITIES, budget: float | None = None):
    """Run the planner's choice on ``scene``; the result records the plan in
    ``diagnostics["plan"]``.  ScopeError when no candidate can run the scene.

    A force-controlled scene is planned at its estimated indentation and solved by the
    choice; then planned again at the indentation that choice solved for, and solved by the
    new choice where it differs (an estimate a little off, or another model's indentation,
    can cross a candidate's predicted tolerance), until the plan of the solved indentation
    chooses the model that solved it (at most :data:`MAX_FORCE_PLANS` solves; in all but
    knife-edge cases one).  So the answer to a force is the plan's answer at its indentation,
    and a force's round trip is exact."""
    from ..registry import run_model

    p = plan(scene, tolerance, quantities, budget)
    tried = []
    while True:
        if p["choice"] is None:
            raise ScopeError(f"auto: {p['reason']}")
        result = run_model(p["choice"]["model"], scene, **p["choice"]["options"])
        tried.append(p["choice"]["label"])
        if scene.force_N is None or not result.converged or len(tried) == MAX_FORCE_PLANS:
            break
        again = plan(scene.designed(result.indentation_m), tolerance, quantities, budget)
        if again["choice"] is None or again["choice"]["label"] == p["choice"]["label"]:
            break
        p = {**again, "scene": scene.to_dict(), "load_control": "force"}
    result.diagnostics["plan"] = compact(p)
    if len(tried) > 1:
        result.diagnostics["plan"]["solved_by_turns"] = tried
    return result
