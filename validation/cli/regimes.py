"""``pillar-xval regimes``: the regime map, which model the planner picks over Phi x zeta/h
for a tolerance, and where the Hooke pillar's sigma0 error passes 5, 20 and 50 %
(:mod:`validation.studies.regimes`)."""

from __future__ import annotations

import sys
from pathlib import Path

from pillar_xval.scenes import load_scene

from ._args import add_scene_arguments, check_out, integer, number


def add_parser(sub) -> None:
    from ..studies.regimes import (DEFAULT_POINTS, HOOKE_LEVELS, PHI_RANGE, POINTS_RANGE,
                                   ZETA_RANGE)

    levels = ", ".join(f"{100 * v:g}" for v in HOOKE_LEVELS)
    p = sub.add_parser(
        "regimes", help="map of the model the planner picks over Phi x zeta/h, with the "
                        "Hooke pillar's sigma0 error",
        description=f"Plan every point of a log grid over the surface fraction Phi "
                    f"({PHI_RANGE[0]:g} to {PHI_RANGE[1]:g}) and zeta/h ({ZETA_RANGE[0]:g} "
                    f"to {ZETA_RANGE[1]:g}) of a base scene, colour the map by the chosen "
                    "model (Hertz, the spring model, the Hooke BEM, the elastic BEM, "
                    f"fem-axisym, fem-3d) and draw where the Hooke pillar's sigma0 model "
                    f"error (the planner's) exceeds {levels} %.  Nothing is solved.  Writes "
                    "regimes.png, regimes.csv, summary.md and regimes.json (last).")
    add_scene_arguments(p, required=False, default="paper-fig3-sparse")
    p.add_argument("--out", type=Path, default=Path("out") / "regimes", metavar="DIR",
                   help="report folder (default out/regimes)")
    p.add_argument("--tolerance", type=number(0.0, 1.0, open_lo=True), default=0.05,
                   metavar="REL",
                   help="relative error allowed on each quantity (default 0.05 = 5 %%)")
    p.add_argument("--quantities", default="F_T,sigma0", metavar="Q,Q",
                   help="comma-separated among F_T, sigma0, a, A (default F_T,sigma0)")
    p.add_argument("--points", type=integer(*POINTS_RANGE), default=DEFAULT_POINTS,
                   metavar="N", help=f"grid points per axis; allowed [{POINTS_RANGE[0]}, "
                                     f"{POINTS_RANGE[1]}] (default {DEFAULT_POINTS})")
    p.set_defaults(func=run)


def _progress(done: int, total: int, elapsed: float) -> None:
    rate = done / elapsed if elapsed > 0 else 0.0
    eta = f", ETA {(total - done) / rate:.0f} s" if rate and done < total else ""
    print(f"[regimes] {done}/{total} points, {elapsed:.0f} s{eta}", file=sys.stderr,
          flush=True)


def run(args) -> int:
    from ..planner.plan import check_request
    from ..studies.regimes import regime_map, write_outputs

    tolerance, quantities, _ = check_request(args.tolerance, args.quantities)
    base = load_scene(args.scene, args.overrides)
    check_out(args.out)
    doc = regime_map(base, tolerance, quantities, args.points, overrides=args.overrides,
                     progress=_progress)
    names = write_outputs(doc, args.out)
    shares = ", ".join(f"{f['label']} {100 * doc['shares'][f['key']]:.0f} %"
                       for f in doc["families"] if doc["shares"][f["key"]])
    print(f"regimes: {doc['timing']['points']} points in {doc['timing']['wall_s']:.1f} s; "
          f"chosen: {shares}; within {100 * tolerance:g} %: "
          f"{100 * doc['within_tolerance_share']:.0f} % of the grid")
    print(f"written to {args.out}/ ({', '.join(names)})")
    return 0
