"""``pillar-xval solve``: run one model on one scene."""

from __future__ import annotations

from pathlib import Path

from scenes import load_scene

from ..models import model_names, run_model
from ._args import add_scene_arguments


def add_parser(sub) -> None:
    p = sub.add_parser("solve", help="solve one scene with one model")
    add_scene_arguments(p)
    p.add_argument("--model", default="bem", choices=model_names(),
                   help="model to run (default: bem, the dense boundary-element solver)")
    p.add_argument("--elements-per-diameter", type=int, default=None, metavar="P",
                   help="BEM: square elements across a pillar diameter (flat scenes: across the "
                        "Hertz contact diameter); default 11")
    p.add_argument("--cells", choices=("centre", "covered"), default=None,
                   help="BEM: 'centre' keeps the paper's cells whose centre lies on the pillar "
                        "top; 'covered' adds edge cells weighted by their covered area "
                        "(smooth convergence); default covered")
    p.add_argument("--contact", choices=("exact", "paper"), default=None,
                   help="BEM contact solver: exact complementarity (default) or the paper's "
                        "contact-radius search")
    p.add_argument("--cells-per-diameter", type=int, default=None, metavar="N",
                   help="bem-fft: square cells across a pillar diameter (flat scenes: across the "
                        "Hertz contact diameter 2 sqrt(R zeta)); default 32")
    p.add_argument("--mesh-size", type=float, default=None, metavar="S",
                   help="fem-axisym: dimensionless mesh refinement factor, 0.5 halves every "
                        "element size; default 1.0")
    p.add_argument("--json", action="store_true", help="print exactly one JSON document")
    p.add_argument("--out", type=Path, default=None,
                   help="folder for result.json, element and pillar CSVs, pressure.png "
                        "(and fields.vtu for the FEM)")
    p.set_defaults(func=run)


def run(args) -> int:
    scene = load_scene(args.scene, args.overrides)
    options = {k: v for k, v in vars(args).items()
               if k not in ("func", "command", "scene", "overrides", "model", "json", "out")}
    if args.out is not None:
        options["vtu_path"] = args.out / "fields.vtu"  # models with volume fields write them
    result = run_model(args.model, scene, **options)
    if args.out is not None:
        from ..report import write_solve_report

        write_solve_report(result, args.out)
    if args.json:
        print(result.to_json())
    else:
        print(result.summary())
        if args.out is not None:
            print(f"written to {args.out}/")
    return 0 if result.converged else 1
