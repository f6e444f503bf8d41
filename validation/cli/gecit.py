"""``pillar-xval gecit``: the Gecit-like study of the Hooke-spring pillar
(:mod:`validation.studies.gecit`)."""

from __future__ import annotations

from pathlib import Path

from scenes import InputError

from ..profiles import EDGE_SKIP, EDGE_WINDOW
from ..studies.gecit import ASPECTS, RATIOS
from ._args import add_engine_arguments, add_scene_arguments, engine_from_args


def add_parser(sub) -> None:
    """Register ``gecit`` on the CLI's subparsers."""
    p = sub.add_parser("gecit", help="Hooke-spring BEM against the elastic-pillar FEM over "
                                     "stiffness and aspect ratios (Gecit-like study)")
    add_scene_arguments(p, required=False, default="single-pillar")
    p.add_argument("--out", type=Path, default=Path("out") / "gecit", help="report folder")
    p.add_argument("--ratios", type=float, nargs="+", default=list(RATIOS), metavar="E_p/E_l",
                   help="pillar-to-lens stiffness ratios (default: 1e-3 ... 1e6)")
    p.add_argument("--aspect", type=float, nargs="+", default=list(ASPECTS), metavar="h/d",
                   help="pillar height over diameter (default 0.25 0.5 1)")
    p.add_argument("--mesh-size", type=float, default=0.5, help="FEM mesh_size (default 0.5)")
    p.add_argument("--elements-per-diameter", type=int, default=None, metavar="P",
                   help="BEM elements per pillar diameter on the coarsest level (default 11)")
    p.add_argument("--bem-levels", type=int, default=3, metavar="N",
                   help="BEM refinements (default 3: 11, 23, 47 elements; errors use the "
                        "BEM's Richardson estimate; 1: the single level as it is)")
    p.add_argument("--edge-window", type=float, nargs=2, default=list(EDGE_WINDOW),
                   metavar=("LO", "HI"),
                   help="edge-exponent fit over LO < (d/2 - r)/(d/2) < HI (default "
                        f"{EDGE_WINDOW[0]:g} {EDGE_WINDOW[1]:g})")
    p.add_argument("--edge-skip", type=int, default=EDGE_SKIP, metavar="SKIP",
                   help=f"profile nodes next to the edge never fitted (default {EDGE_SKIP}: "
                        "four P2 elements, where nodal pressures alternate)")
    p.add_argument("--edge-nodes", type=int, default=None, metavar="N",
                   help="fit instead over the N nodes nearest the edge after the skipped ones")
    p.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="the same as --workers (kept for older scripts)")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    """Run or resume every case, write the table and figures; exit 1 if a case failed."""
    from ..studies.gecit import check_fit_options, gecit_study, study_scenes, table_text, \
        write_report

    if args.jobs is not None:
        if args.jobs < 1:
            raise InputError(f"--jobs {args.jobs}: must be >= 1")
        args.workers = args.workers or args.jobs
    check_fit_options(args.edge_window, args.edge_nodes, args.edge_skip, args.bem_levels)
    scenes = study_scenes(args.scene, args.overrides, args.ratios, args.aspect)
    with engine_from_args(args, "gecit") as engine:
        doc = gecit_study(scenes, args.out / "cases", engine=engine, mesh_size=args.mesh_size,
                          elements_per_diameter=args.elements_per_diameter,
                          bem_levels=args.bem_levels, edge_window=args.edge_window,
                          edge_nodes=args.edge_nodes, edge_skip=args.edge_skip)
    names = write_report(doc, args.out, {"base_scene": args.scene, "overrides": args.overrides})
    rows, meta = doc["rows"], doc["meta"]
    print("Hooke-spring BEM vs elastic-pillar FEM: err = (BEM - FEM)/FEM with the BEM's "
          "Richardson estimate (+-U: its GCI band) when refined; 'spring F': closed-form spring "
          "model vs FEM")
    print(table_text(rows))
    print("lambda: sigma ~ (d/2 - r)^-lambda fitted in the window shown (R^2 means little when "
          "lambda ~ 0); plateau = sigma(d/4)/sigma0; outer10% = share of the pillar force on "
          "r > 0.45 d; t_FEM, t_BEM: solve times (s)")
    print(f"{len(rows)} cases ({meta['cached_cases']} from the cache) in "
          f"{meta['wall_time_s']:.1f} s on {meta['executor']}; report: {args.out}/ "
          f"({', '.join(names)})")
    return 0 if all(r["status"] == "ok" for r in rows) else 1
