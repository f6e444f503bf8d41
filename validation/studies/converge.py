"""Grid convergence of one model: N refinement levels on the engine, observed order,
Richardson estimate and GCI per quantity (F_T, sigma0, a, A), with tables and a plot."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import Scene

from ..engine import Engine
from ..registry import FLOOR_QUANTITIES, QUANTITIES
from ..output.formatting import number, percent
from ._ladder import level_cases, study_levels

# The report folder's files, report (converge.json) last: its presence means a whole report.
OUTPUTS = ("levels.csv", "gci.csv", "convergence.png", "converge.json")


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
            + f"{number(g['order'], '.3f'):>9}{number(g['f_exact'], '.7g'):>14}"
            + f"{percent(g['gci_fine'], '.3g', ''):>10}"
            + f"{number(g['asymptotic_ratio'], '.3f'):>16}  {g['status']}")
    return "\n".join(lines)


def studied(data: dict) -> tuple:
    """The quantities of a study: :data:`QUANTITIES`, and the floor's on a mixed contact."""
    return tuple(q for q in QUANTITIES + FLOOR_QUANTITIES if q.key in data["studies"])


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
