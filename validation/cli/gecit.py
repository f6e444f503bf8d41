"""``pillar-xval gecit``: the Gecit-like study of the Hooke-spring pillar
(:mod:`validation.studies.gecit`)."""

from __future__ import annotations

from pathlib import Path

from ..analysis.profiles import EDGE_SKIP, EDGE_WINDOW
from ..studies.gecit import ASPECTS, CONVENTION, RATIOS
from ._args import (add_engine_arguments, add_output_arguments,
                    add_refinement_arguments, add_scene_arguments, check_out,
                    engine_from_args, integer, number, print_json, study_status)
from ._exit import EXIT_BAD_INPUT, EXIT_TOOL_FAILURE

FEM_MESH_SIZE = 0.5


def add_parser(sub) -> None:
    """Register ``gecit`` on the CLI's subparsers."""
    p = sub.add_parser(
        "gecit", help="Hooke-spring BEM against the elastic-pillar FEM over stiffness and "
                      "aspect ratios (Gecit-like study)",
        description="For each pillar-to-lens stiffness ratio E_p/E_l and aspect ratio h/d, "
                    "solve the single-pillar scene with the FEM (elastic pillar) and the BEM "
                    "(Hooke-spring pillar, on --levels refinements and Richardson-"
                    f"extrapolated), and measure the FEM's pressure profile.  {CONVENTION}.")
    add_scene_arguments(p, required=False, default="single-pillar")
    p.add_argument("--ratios", type=number(0.0, open_lo=True), nargs="+", default=list(RATIOS),
                   metavar="E_p/E_l",
                   help="pillar-to-lens stiffness ratios, > 0 (default: 1e-3 ... 1e6); the "
                        "substrate gets the pillars' modulus")
    p.add_argument("--aspect", type=number(0.0, open_lo=True), nargs="+", default=list(ASPECTS),
                   metavar="h/d", help="pillar height over diameter, > 0 (default 0.25 0.5 1)")
    add_refinement_arguments(p, ladder=True, families=("elements_per_diameter", "mesh_size"),
                             defaults={"elements_per_diameter": 11, "mesh_size": FEM_MESH_SIZE})
    p.add_argument("--levels", type=integer(1, 5), default=3, metavar="N",
                   help="BEM refinements (default 3: 11, 23, 47 elements; errors use the BEM's "
                        "Richardson estimate; 1: the single level as it is); the FEM runs once "
                        "at --mesh-size; allowed [1, 5]")
    p.add_argument("--edge-window", type=number(0.0, 1.0), nargs=2, default=list(EDGE_WINDOW),
                   metavar=("LO", "HI"),
                   help="edge-exponent fit over LO < (d/2 - r)/(d/2) < HI (default "
                        f"{EDGE_WINDOW[0]:g} {EDGE_WINDOW[1]:g})")
    p.add_argument("--edge-skip", type=integer(0, 10_000), default=EDGE_SKIP, metavar="SKIP",
                   help=f"profile nodes next to the edge never fitted (default {EDGE_SKIP}: "
                        "four P2 elements, where nodal pressures alternate)")
    p.add_argument("--edge-nodes", type=integer(3, 10_000), default=None, metavar="N",
                   help="fit instead over the N nodes nearest the edge after the skipped ones")
    add_output_arguments(p, "report folder (default out/gecit)")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    """Run or resume every case, write the table and figures; exit 1 if a case failed."""
    from ..output.report import clear_outputs
    from ..studies.gecit import (OUTPUTS, check_fit_options, gecit_study, report_doc,
                                 study_scenes, table_text, write_report)

    mesh_size = FEM_MESH_SIZE if args.mesh_size is None else args.mesh_size
    check_fit_options(args.edge_window, args.edge_nodes, args.edge_skip, args.levels,
                      mesh_size, args.elements_per_diameter)
    scenes = study_scenes(args.scene, args.overrides, args.ratios, args.aspect)
    out = check_out(args.out or Path("out") / "gecit")
    clear_outputs(out, OUTPUTS, "gecit")
    with engine_from_args(args, "gecit") as engine:
        doc = gecit_study(scenes, out / "cases", engine=engine, mesh_size=mesh_size,
                          elements_per_diameter=args.elements_per_diameter,
                          bem_levels=args.levels, edge_window=args.edge_window,
                          edge_nodes=args.edge_nodes, edge_skip=args.edge_skip)
    extra = {"base_scene": args.scene, "overrides": args.overrides}
    names = write_report(doc, out, extra)
    rows, meta = doc["rows"], doc["meta"]
    if args.json:
        print_json(report_doc(doc, extra))
    else:
        print(f"Hooke-spring BEM vs elastic-pillar FEM, {CONVENTION}: err = (BEM - FEM)/FEM "
              "with the BEM's Richardson estimate (+-U: its GCI band) when refined; "
              "'spring F': closed-form spring model vs FEM")
        print(table_text(rows))
        print("lambda: sigma ~ (d/2 - r)^-lambda fitted in the window shown (R^2 means little "
              "when lambda ~ 0); plateau = sigma(d/4)/sigma0; outer10% = share of the pillar "
              "force on r > 0.45 d; t_FEM, t_BEM: solve times (s)")
        print(f"{len(rows)} cases ({meta['cached_cases']} from the cache) in "
              f"{meta['wall_time_s']:.1f} s on {meta['executor']}; report: {out}/ "
              f"({', '.join(names)})")
    def which(r):
        return f"E_p/E_l={r['ratio']:g} h/d={r['aspect']:g}: {r['status']}"

    failed = [(EXIT_BAD_INPUT if r.get("refused") else EXIT_TOOL_FAILURE, which(r))
              for r in rows if r["status"].startswith("failed")]
    return study_status("gecit", failed,
                        [which(r) for r in rows if r["status"] == "not converged"])
