"""Grid convergence of one model: N refinement levels on the engine, observed order,
Richardson estimate and GCI per quantity (F_T, sigma0, a, A), with tables and a plot."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import InputError, Scene

from ..engine import Case, Engine, Outcome
from ..registry import (FLOOR_QUANTITIES, QUANTITIES, check_option, flag, get_model,
                        ladder_for, quantity_values)
from ..analysis.verification import study

# The report folder's files, report (converge.json) last: its presence means a whole report.
OUTPUTS = ("levels.csv", "gci.csv", "convergence.png", "converge.json")
LEVELS_RANGE = (2, 8)


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


def study_levels(model: str, scene: Scene, outcomes: list[Outcome]) -> dict:
    """The verification study of finished levels (coarse to fine).

    Returns a JSON-ready dict with the ladder, one row per level and, per quantity, the
    :func:`validation.analysis.verification.study` dict, ``label`` (the model with its pillar
    model, as tables and plots name it), plus ``results`` (the ContactResults, not JSON).  A
    level that failed raises its error.
    """
    ladder = ladder_for(model)
    rows, results = [], []
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


def converge_study(model: str, scene: Scene, levels: int, cache_dir: Path, *,
                   coarsest: float | None = None, engine: Engine | None = None,
                   tag: str = "converge", vtu_finest: bool = False,
                   options: dict | None = None) -> dict:
    """Run (or resume from ``cache_dir``) ``levels`` refinements and study each quantity
    (see :func:`study_levels`); ``vtu_finest`` asks for the finest level's VTU (its path is in
    ``levels[-1]['vtu']``).  Without ``engine`` the levels run serially in this process."""
    cases = level_cases(model, scene, levels, coarsest=coarsest, tag=tag, vtu_finest=vtu_finest,
                        options=options)
    own = engine is None
    engine = engine or Engine("serial", label=tag)
    try:
        outcomes = engine.run(cases, cache_dir, label=tag)
    finally:
        if own:
            engine.close()
    return study_levels(model, scene, outcomes)


def study_table(data: dict) -> str:
    """Plain-text table of the per-quantity GCI results."""
    lines = [f"{'quantity':<8}{'finest':>13}{'':5}{'order p':>9}{'Richardson':>14}"
             f"{'GCI_fine':>10}{'GCI23/r^pGCI12':>16}  status"]
    for q in studied(data):
        g = data["studies"][q.key]["gci"]
        lines.append(
            f"{q.key:<8}{g['f'][0]:>13.6g} {q.unit:<4}"
            + f"{_num(g['order'], '.3f'):>9}{_num(g['f_exact'], '.7g'):>14}"
            + f"{_num(None if g['gci_fine'] is None else 100 * g['gci_fine'], '.3g', '%'):>10}"
            + f"{_num(g['asymptotic_ratio'], '.3f'):>16}  {g['status']}")
    return "\n".join(lines)


def studied(data: dict) -> tuple:
    """The quantities of a study: :data:`QUANTITIES`, and the floor's on a mixed contact."""
    return tuple(q for q in QUANTITIES + FLOOR_QUANTITIES if q.key in data["studies"])


def _num(x, fmt: str, suffix: str = "") -> str:
    return "-" if x is None else f"{x:{fmt}}{suffix}"


def levels_csv(data: dict) -> str:
    """CSV of the levels (coarse to fine): option value, h and every quantity (SI)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    quantities = studied(data)
    w.writerow(["level", data["ladder"]["option"], "h", *(f"{q.key}_{q.unit}" for q in quantities),
                "converged", "wall_time_s"])
    for r in data["levels"]:
        w.writerow([r["level"], r["value"], repr(r["h"]), *(repr(r[q.key]) for q in quantities),
                    r["converged"], f"{r['wall_time_s']:.4g}"])
    return buf.getvalue()


def gci_csv(data: dict) -> str:
    """CSV of the per-quantity verification results (GCI as fractions, SI values)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    cols = ["order", "f_exact", "gci_fine", "gci_coarse", "uncertainty", "asymptotic_ratio",
            "fallback_uncertainty", "status"]
    w.writerow(["quantity", "unit", "f_finest", *cols, "lsq_order", "lsq_r_squared"])
    for q in studied(data):
        s = data["studies"][q.key]
        g = s["gci"]
        w.writerow([q.key, q.unit, repr(g["f"][0]), *("" if g[c] is None else g[c] for c in cols),
                    "" if s["lsq"]["order"] is None else s["lsq"]["order"],
                    "" if s["lsq"]["r_squared"] is None else s["lsq"]["r_squared"]])
    return buf.getvalue()


def write_report(data: dict, out: Path) -> list[str]:
    """:data:`OUTPUTS` in ``out`` (converge.json last); returns their names."""
    from ..output.plots import plot_convergence

    doc = {k: v for k, v in data.items() if k != "results"}
    write_atomic(out / "levels.csv", levels_csv(doc))
    write_atomic(out / "gci.csv", gci_csv(doc))
    plot_convergence(doc, out / "convergence.png")
    write_atomic(out / "converge.json", json.dumps(doc, indent=2, allow_nan=False))
    return list(OUTPUTS)
