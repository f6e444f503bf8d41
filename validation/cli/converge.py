"""``pillar-xval converge``: a model on N refinement levels, observed order, Richardson
estimate and GCI per quantity (F_T, sigma0, a, A), with a log-log plot, CSV and JSON."""

from __future__ import annotations

from pathlib import Path

from scenes import load_scene

from ..models import model_names
from ._args import add_engine_arguments, add_scene_arguments, engine_from_args


def add_parser(sub) -> None:
    """Register ``converge`` on the CLI's subparsers."""
    p = sub.add_parser("converge", help="grid convergence study of one model: order, "
                                        "Richardson estimate, GCI")
    add_scene_arguments(p)
    p.add_argument("--model", default="fem-axisym", choices=model_names(),
                   help="model to refine (default fem-axisym)")
    p.add_argument("--levels", type=int, default=3, metavar="N",
                   help="refinement levels, >= 2 (3 or more give an observed order); default 3")
    p.add_argument("--coarsest", type=float, default=None, metavar="VALUE",
                   help="value of the refined option on the coarsest level (bem: elements per "
                        "diameter, default 11; fem-axisym: mesh_size, default 1.0)")
    p.add_argument("--out", type=Path, default=None,
                   help="report folder (default out/converge/<scene>-<model>)")
    add_engine_arguments(p, "recompute cached levels")
    p.set_defaults(func=run)


def run(args) -> int:
    """Study, write the report folder, print the table; exit 1 if a level did not converge."""
    from ..studies.converge import converge_study, study_table, write_report

    scene = load_scene(args.scene, args.overrides)
    out = args.out or Path("out") / "converge" / f"{scene.name}-{args.model}"
    with engine_from_args(args, "converge") as engine:
        data = converge_study(args.model, scene, args.levels, out / "cases",
                              coarsest=args.coarsest, engine=engine)
    names = write_report(data, out)
    print(f"{args.model} on {scene.name}: {args.levels} levels of {data['ladder']['option']}")
    print(study_table(data))
    print(f"report: {out}/ ({', '.join(names)})")
    return 0 if data["all_converged"] else 1
