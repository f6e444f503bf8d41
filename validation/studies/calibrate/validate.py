"""The planner validated: on seeded scenes it never saw, is the planned model within
tolerance of the best reference the toolkit has, and is it cheap?

Scenes: a Latin-hypercube sample of the paper's family (seed :data:`VALIDATION_SEED`, not the
calibration's), a smaller stiff-substrate sample and flat scenes
(:mod:`.scenes`).  The best reference per regime:

- one pillar touches: the elastic pillar, fem-axisym's Richardson estimate over mesh_size
  2, 1, 0.5 (blocks 1e5 radii wide: truncation ~5e-6);
- several pillars touch: the Hooke pillars, the cross-checked Richardson estimate of the
  dense BEM (P = 11, 15, 21) and the FFT BEM (N = 32, 48, 64) of
  :func:`validation.studies.tradeoff.reference_values`.  The Hooke pillar's own error there
  is measured by the lattice study (fem-3d) and reported by the plan as unavoidable; a
  fem-3d Richardson reference on every lattice scene would take hours on this machine;
- flat: the half-spaces, cross-checked over both BEMs and fem-axisym.

Every candidate predicted to cost at most :data:`RUN_FACTOR` times the planned one runs too
(three timed repeats below 1 s), so that the cheapest candidate actually within tolerance is
known.  A scene passes on accuracy when the planned model's error is within tolerance for
every requested quantity, and on cost when its measured time is within 2x of the cheapest
candidate within tolerance (:data:`TIME_FLOOR` seconds count as equal: below it a contended
machine's timings are noise).

The hand-entered candidates (fem-3d and the elastic-pillar BEMs, whose ``source`` starts with
"hand") are left out by default (:func:`measured_only`): on a lattice this validation's
reference has Hooke pillars, which would judge an elastic-pillar choice against the wrong
physics, and each elastic pillar kind of the sample would cost a compliance build.  Judging
them needs fem-3d references on the lattice scenes (hours).
"""

from __future__ import annotations

import csv
import io
import json
import time
from pathlib import Path

from outcome import write_atomic

from ...engine import Case, Engine
from ...registry import MODELS, quantity_values
from ...analysis.verification import gci_three
from .run import is_hand
from .scenes import flat_scenes, lattice_scenes
from ...planner.plan import DEFAULT_QUANTITIES, DEFAULT_TOLERANCE, plan
from ...planner.tables import PlannerData, load_data
from ..tradeoff import reference_values

__all__ = ["VALIDATION_SEED", "summary_text", "validate_planner", "validation_scenes",
           "write_outputs"]

VALIDATION_SEED = 77
RUN_FACTOR = 3.0
RUN_ALWAYS_S = 0.5   # candidates predicted faster than this always run
TIME_FACTOR = 2.0
TIME_FLOOR = 0.05
REFERENCE_TEXT = {
    "single": "elastic pillar: fem-axisym Richardson (mesh_size 2, 1, 0.5)",
    "multi": "Hooke pillars: dense + FFT BEM Richardson, cross-checked (the Hooke error "
             "itself: the lattice study against fem-3d)",
    "flat": "half-spaces: dense + FFT BEM + fem-axisym Richardson, cross-checked"}


def validation_scenes(n_paper: int = 50, n_stiff: int = 6, n_flat: int = 4,
                      seed: int = VALIDATION_SEED) -> list:
    """The validation's scenes (see the module docstring)."""
    return (lattice_scenes(n_paper, seed, "pillars", "v")
            + lattice_scenes(n_stiff, seed + 1, "lens", "w")
            + flat_scenes((3e-4, 3e-3, 0.03, 0.3)[:n_flat]))


def _case(model, scene, options, tag) -> Case:
    return Case(model, scene, dict(options), repeats=3, single_above=1.0, tag=tag)


def _scene_cases(entry: dict, p: dict) -> tuple[list, list]:
    """(reference cases, candidate cases) of one scene."""
    reg = p["regime"]["name"]
    ref = [_case(m.name, entry["scene"], m.ladder.options_at(v), f"{entry['name']} ref")
           for m in MODELS.values() for v in m.reference_rungs.get(reg, ())]
    planned = p["choice"]["time_s"] if p["choice"] else 0.0
    limit = max(RUN_FACTOR * planned, RUN_ALWAYS_S)
    cands = [_case(c["model"], entry["scene"], c["options"], f"{entry['name']} {c['label']}")
             for c in p["candidates"]
             if c["eligible"] and (c["time_s"] <= limit or (
                 p["choice"] and c["label"] == p["choice"]["label"]))]
    return ref, cands


def _reference(reg: str, outcomes: list, quantities) -> dict:
    rows = []
    for o in outcomes:
        if not o.ok or not o.result.converged:
            continue
        ladder = MODELS[o.case.model].ladder
        value = o.case.options[ladder.option]
        rows.append({"model": o.case.model, "h": ladder.size(value), "converged": True,
                     "wall_time_s": o.timing["wall_time_s"], **quantity_values(o.result)})
    out = {}
    if reg == "single":
        fem = sorted(rows, key=lambda r: r["h"])
        for q in quantities:
            if len(fem) < 3:
                out[q] = None
                continue
            g = gci_three([r["h"] for r in fem[:3]], [r[q] for r in fem[:3]])
            out[q] = {"value": g.f_exact if g.status == "ok" else fem[0][q],
                      "band": g.uncertainty if g.status == "ok" else g.fallback_uncertainty,
                      "how": f"fem-axisym Richardson ({g.status})"}
        return out
    refs = reference_values(rows)
    for q in quantities:
        r = refs[q]
        out[q] = {"value": r["value"], "band": r["band"],
                  "how": f"{r['model']} ({r['basis'] or r['status']})"}
    return out


def _errors(result, ref: dict, quantities) -> dict | None:
    if ref is None or any(ref.get(q) is None for q in quantities):
        return None
    vals = quantity_values(result)
    return {q: abs(vals[q] - ref[q]["value"]) / abs(ref[q]["value"])
            for q in quantities if ref[q]["value"]}


def measured_only(data: PlannerData) -> PlannerData:
    """``data`` without its hand-entered candidates (module docstring)."""
    from dataclasses import replace

    return replace(data, candidates=[c for c in data.candidates if not is_hand(c)])


def validate_planner(out: Path, engine: Engine | None = None, *, scenes=None,
                     tolerance: float = DEFAULT_TOLERANCE, quantities=DEFAULT_QUANTITIES,
                     data: PlannerData | None = None) -> dict:
    """Plan, run and judge every scene (cases cached in ``out/cases``); returns the rows and
    the totals."""
    t0 = time.perf_counter()
    data = measured_only(load_data()) if data is None else data
    scenes = validation_scenes() if scenes is None else scenes
    plans = [plan(e["scene"], tolerance, quantities, data=data) for e in scenes]
    batches = [_scene_cases(e, p) for e, p in zip(scenes, plans)]
    flat = [c for ref, cands in batches for c in ref + cands]
    own = engine is None
    engine = engine or Engine("serial", label="validate-plan")
    try:
        outcomes = engine.run(flat, Path(out) / "cases", label="validate-plan")
    finally:
        if own:
            engine.close()
    rows, k = [], 0
    for entry, p, (ref_cases, cand_cases) in zip(scenes, plans, batches):
        mine = outcomes[k:k + len(ref_cases) + len(cand_cases)]
        k += len(mine)
        rows.append(_judge(entry, p, mine[:len(ref_cases)], mine[len(ref_cases):],
                           tolerance, quantities))
    judged = [r for r in rows if r["accurate"] is not None]
    totals = {"scenes": len(rows), "judged": len(judged),
              "accurate": sum(r["accurate"] for r in judged),
              "cheap": sum(bool(r["cheap"]) for r in judged),
              "cheap_strict": sum(bool(r["cheap_strict"]) for r in judged),
              "tolerance": tolerance, "quantities": list(quantities),
              "executor": engine.describe(), "wall_time_s": time.perf_counter() - t0}
    totals["accurate_share"] = totals["accurate"] / max(1, len(judged))
    totals["cheap_share"] = totals["cheap"] / max(1, len(judged))
    return {"rows": rows, "totals": totals, "reference_text": REFERENCE_TEXT}


def _judge(entry, p, ref_outcomes, cand_outcomes, tolerance, quantities) -> dict:
    reg = p["regime"]["name"]
    ref = _reference(reg, ref_outcomes, quantities)
    tried = []
    for o in cand_outcomes:
        label = o.case.tag.split(" ", 1)[1]
        if not o.ok:
            tried.append({"label": label, "error": str(o.error)})
            continue
        errs = _errors(o.result, ref, quantities)
        tried.append({"label": label, "time_s": o.timing["wall_time_s"],
                      "converged": bool(o.result.converged), "errors": errs,
                      "within": errs is not None and o.result.converged
                      and all(v <= tolerance for v in errs.values())})
    choice = p["choice"]
    row = {"name": entry["name"], "family": entry.get("family"), "phi": entry.get("phi"),
           "zeta_um": entry.get("zeta_um"), "ratio": entry.get("ratio"),
           "regime": p["regime"]["label"], "reference": REFERENCE_TEXT[reg],
           "reference_values": ref, "planned": choice["label"] if choice else None,
           "planned_within_predicted": choice["within_tolerance"] if choice else None,
           "predicted": choice["predicted_errors"] if choice else None,
           "predicted_time_s": choice["time_s"] if choice else None, "reason": p["reason"],
           "unavoidable_error": p["unavoidable_error"], "tried": tried,
           "accurate": None, "cheap": None, "cheap_strict": None}
    planned = next((t for t in tried if choice and t["label"] == choice["label"]), None)
    if planned is None or planned.get("errors") is None:
        row["note"] = "no reference or the planned run failed"
        return row
    row.update(actual=planned["errors"], time_s=planned["time_s"],
               accurate=bool(planned["within"]))
    ok = [t for t in tried if t.get("within")]
    if ok:
        cheapest = min(ok, key=lambda t: t["time_s"])
        row.update(cheapest=cheapest["label"], cheapest_time_s=cheapest["time_s"])
        row["cheap_strict"] = planned["time_s"] <= TIME_FACTOR * cheapest["time_s"]
        row["cheap"] = row["cheap_strict"] or planned["time_s"] <= TIME_FLOOR
    return row


CSV_COLUMNS = ("name", "family", "regime", "phi", "zeta_um", "ratio", "planned",
               "predicted_F_T", "predicted_sigma0", "actual_F_T", "actual_sigma0", "accurate",
               "time_s", "cheapest", "cheapest_time_s", "cheap", "cheap_strict")


def _flat_row(r: dict) -> dict:
    out = {k: r.get(k) for k in CSV_COLUMNS}
    for q in ("F_T", "sigma0"):
        out[f"predicted_{q}"] = (r.get("predicted") or {}).get(q)
        out[f"actual_{q}"] = (r.get("actual") or {}).get(q)
    return out


def summary_text(doc: dict) -> str:
    """The validation table, its totals and the misses."""
    t = doc["totals"]

    def pct(v):
        return "-" if v is None else f"{100 * v:.2g}%"

    head = (f"{'scene':<7}{'regime':<15}{'Phi':>8}{'zeta um':>9}{'Ep/El':>9}  "
            f"{'planned':<20}{'pred max':>9}{'actual max':>11}{'t s':>8}  "
            f"{'cheapest within':<20}{'t s':>8}  verdict")
    lines = [head, "-" * len(head)]
    for r in doc["rows"]:
        pred = max(r["predicted"].values()) if r.get("predicted") else None
        act = max(r["actual"].values()) if r.get("actual") else None
        verdict = ("?" if r["accurate"] is None else
                   ("ok" if r["accurate"] else "MISS accuracy")
                   + ("" if r["cheap"] in (None, True) else ", MISS time"))
        lines.append(
            f"{r['name']:<7}{r['regime']:<15}{_num(r['phi'], '.3g'):>8}"
            f"{_num(r['zeta_um'], '.3g'):>9}{_num(r['ratio'], '.3g'):>9}  "
            f"{(r['planned'] or '-'):<20}{pct(pred):>9}{pct(act):>11}"
            f"{_num(r.get('time_s'), '.3g'):>8}  {(r.get('cheapest') or '-'):<20}"
            f"{_num(r.get('cheapest_time_s'), '.3g'):>8}  {verdict}")
    lines += ["", f"accuracy: {t['accurate']}/{t['judged']} scenes within "
                  f"{100 * t['tolerance']:.2g} % on {', '.join(t['quantities'])} "
                  f"({100 * t['accurate_share']:.1f} %)",
              f"cost: {t['cheap']}/{t['judged']} within {TIME_FACTOR:g}x of the cheapest "
              f"candidate within tolerance, or under {TIME_FLOOR:g} s "
              f"({100 * t['cheap_share']:.1f} %); strictly within {TIME_FACTOR:g}x: "
              f"{t['cheap_strict']}/{t['judged']}",
              "references: " + "; ".join(f"{k}: {v}" for k, v in doc["reference_text"].items())]
    misses = [r for r in doc["rows"] if r["accurate"] is False or r["cheap"] is False]
    if misses:
        lines.append("misses:")
        for r in misses:
            lines.append(f"  {r['name']}: planned {r['planned']} (predicted "
                         + ", ".join(f"{q} {pct(v)}" for q, v in r["predicted"].items())
                         + "; actual " + ", ".join(f"{q} {pct(v)}" for q, v in
                                                   r["actual"].items())
                         + f"; {r['time_s']:.3g} s); cheapest within tolerance "
                         f"{r.get('cheapest')} ({_num(r.get('cheapest_time_s'), '.3g')} s)")
    return "\n".join(lines)


def _num(v, fmt):
    return "-" if v is None else format(v, fmt)


def write_outputs(doc: dict, out: Path) -> list:
    """planner_validation.json, .csv and summary.txt in ``out``."""
    out = Path(out)
    write_atomic(out / "planner_validation.json", json.dumps(doc, indent=1, allow_nan=False))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS)
    w.writeheader()
    for r in doc["rows"]:
        w.writerow({k: ("" if v is None else v) for k, v in _flat_row(r).items()})
    write_atomic(out / "planner_validation.csv", buf.getvalue())
    write_atomic(out / "summary.txt", summary_text(doc) + "\n")
    return ["planner_validation.json", "planner_validation.csv", "summary.txt"]
