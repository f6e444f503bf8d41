"""``pillar-xval figures --out DIR``: the paper's Figs. 3-8 from sweeps on the engine, each a
PNG with the CSV of its data, and ``figures.md`` (the paper's numbers beside ours)."""

from __future__ import annotations

import json
from pathlib import Path

from pillar_xval.scenes import InputError

from ._args import add_engine_arguments, check_out, engine_from_args, pillar_models_type

DEFAULT_MODEL = "bem-richardson"


def add_parser(sub) -> None:
    p = sub.add_parser(
        "figures", help="the paper's Figs. 3-8 (PNG + CSV each) and figures.md",
        description="Reproduce the paper's Figs. 3-8 with Table 1 parameters (E_s = E_p): every "
                    "scene runs on the engine (cached in DIR/cases: a rerun resumes), the "
                    "master curves are fitted, the single-pillar threshold is bisected on the "
                    "exact solver, and DIR gets fig3.png ... fig8.png, their CSVs, "
                    "figures.json, figures.md (the paper's claims checked), claims.csv and "
                    "timing.json.  --pillars elastic or both: the elastic-pillar BEM (its "
                    "pillar compliance built once per pillar kind and cached on disk).")
    p.add_argument("--out", type=Path, default=Path("out") / "figures",
                   help="output folder (default out/figures)")
    p.add_argument("--model", default=DEFAULT_MODEL,
                   help="dense model of the figures: bem-richardson (default: the dense BEM at "
                        "P and 2P - 1, extrapolated) or bem")
    p.add_argument("--elements-per-diameter", type=int, default=None, metavar="P",
                   help="square elements across a pillar (bem-richardson: the coarse level); "
                        "default 5")
    p.add_argument("--pillars", type=pillar_models_type, default="hooke", metavar="MODEL",
                   help="the pillar model: 'hooke', the paper's uniformly shortening spring "
                        "(default), 'elastic', the whole pillar's top compliance, or 'both': "
                        "the two on the same axes, and figures.md checks each of the paper's "
                        "claims with each")
    p.add_argument("--quick", "--coarse", action="store_true",
                   help="a coarse version of every figure (a few seconds; for tests)")
    p.add_argument("--json", action="store_true",
                   help="print exactly one JSON document (the numbers and the files written)")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..studies.figures import DENSE_MODELS, run_figures
    from ..studies.figures.scenes import FigureGrid

    if args.model not in DENSE_MODELS:
        raise InputError(f"--model {args.model!r}: the figures draw pressure maps from the "
                         f"dense model's elements; allowed: {', '.join(DENSE_MODELS)}")
    p = args.elements_per_diameter
    if p is not None and not 3 <= p <= 41:
        raise InputError(f"--elements-per-diameter {p}: allowed range is [3, 41]")
    grid = FigureGrid.quick(p or 5) if args.quick else FigureGrid.full(p or 5)
    check_out(args.out)
    with engine_from_args(args, "figures") as engine:
        kw = {} if args.pillars == ("hooke",) else {"pillars": args.pillars}
        doc = run_figures(args.out, grid, model=args.model, engine=engine, **kw)
    t = doc["timing"]
    failed = doc["failed"]
    if args.json:
        if "variants" in doc:
            summary = {k: doc[k] for k in ("pillars", "model", "options", "grid", "timing",
                                           "paths", "failed", "claims")}
            summary["variants"] = {v: _summary(d) for v, d in doc["variants"].items()}
        else:
            summary = _summary(doc)
            summary.update({k: doc.get(k) for k in ("timing", "paths", "failed", "claims")})
        print(json.dumps(summary, default=float))
    else:
        print(f"figures: {t['unique_cases']} scenes ({t['cases_computed']} computed) and "
              f"{t['threshold_solves']} threshold solves in {t['total_s']:.1f} s "
              f"(scenes {t['scenes_s']:.1f} s, bisection {t['threshold_bisection_s']:.1f} s, "
              f"fits and plots {t['analysis_and_plots_s']:.1f} s) on {t['executor']}")
        print(f"written to {args.out}/: fig3.png ... fig8.png, their CSVs, figures.md, "
              f"claims.csv, figures.json, timing.json")
        claims = doc.get("claims") or []
        if claims:
            holds = ", ".join(f"{v} pillars {sum(c[v]['holds'] is True for c in claims)} of "
                              f"{len(claims)}" for v in args.pillars)
            print(f"the paper's claims that hold (figures.md, claims.csv): {holds}"
                  + ("; judged on the coarse --quick grid: a test of the pipeline, not of "
                     "the paper" if args.quick else ""))
        if failed:
            print(f"{len(failed)} case(s) failed or did not converge (see figures.md)")
    return 1 if failed else 0


def _summary(doc: dict) -> dict:
    """One pillar model's numbers for --json."""
    keep = ("model", "options", "grid", "fig3", "fig3_search", "failed")
    summary = {k: doc[k] for k in keep}
    summary["pillars"] = doc.get("pillars", "hooke")
    summary["thresholds"] = {k: doc["thresholds"][k] for k in
                             ("band", "common_exponent", "area_exponent", "zeta_t_over_h")}
    summary["curves"] = [{k: c[k] for k in ("ratio", "zeta_um", "phi_s_fit", "phi_h_fit",
                                            "fit_rms", "phi_h_band")}
                         for c in doc["thresholds"]["curves"]]
    summary["exact_phi_s"] = doc["thresholds"]["exact"]
    return summary
