"""``pillar-xval compare``: BEM (Hooke pillar) against FEM (elastic pillar) on one scene, with
each model's numerical uncertainty beside every difference (:mod:`validation.studies.compare`)."""

from __future__ import annotations

from pathlib import Path

from scenes import load_scene

from ..studies.compare import FEM_COARSEST
from ._args import add_engine_arguments, add_scene_arguments, engine_from_args


def add_parser(sub) -> None:
    """Register ``compare`` on the CLI's subparsers."""
    p = sub.add_parser("compare", help="BEM (Hooke pillar) against FEM (elastic pillar) with "
                                       "the FEM's GCI uncertainty")
    add_scene_arguments(p)
    p.add_argument("--out", type=Path, default=None,
                   help="report folder (default out/compare/<scene>)")
    p.add_argument("--fem-levels", type=int, default=3, metavar="N",
                   help="FEM refinements for the GCI (default 3)")
    p.add_argument("--fem-coarsest", type=float, default=FEM_COARSEST, metavar="MESH_SIZE",
                   help=f"FEM mesh_size of the coarsest level, halved per level (default "
                        f"{FEM_COARSEST:g})")
    p.add_argument("--bem-levels", type=int, default=3, metavar="N",
                   help="BEM refinements (default 3, for its own GCI; 1: no BEM uncertainty)")
    p.add_argument("--elements-per-diameter", type=int, default=None, metavar="P",
                   help="BEM elements per diameter on its coarsest level (default 11)")
    p.add_argument("--no-render", action="store_true", help="skip the pyvista render")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    """Run both models, write the report folder, print the table; exit 1 if a run did not
    converge."""
    from ..studies.compare import compare_study

    scene = load_scene(args.scene, args.overrides)
    out = args.out or Path("out") / "compare" / scene.name
    with engine_from_args(args, "compare") as engine:
        report = compare_study(scene, out, engine=engine, fem_levels=args.fem_levels,
                               fem_coarsest=args.fem_coarsest, bem_levels=args.bem_levels,
                               elements_per_diameter=args.elements_per_diameter,
                               render=not args.no_render)
    print(report["title"])
    print(report["table"])
    print(f"render: {report['render']}")
    print(f"report: {out}/ (report.json, summary.md, profiles.png, profiles.csv"
          + (", fem_finest.vtu" if report["vtu"] else "")
          + (", fem_stress_3d.png" if (out / "fem_stress_3d.png").exists() else "") + ")")
    return 0 if report["converged"] else 1
