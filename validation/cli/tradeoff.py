"""``pillar-xval tradeoff``: wall time, peak memory and error of each model on its ladder
(:mod:`validation.studies.tradeoff`)."""

from __future__ import annotations

from pathlib import Path

from scenes import InputError, load_scene

from ..ladders import LADDERS
from ._args import add_engine_arguments, add_scene_arguments, engine_from_args


def add_parser(sub) -> None:
    p = sub.add_parser(
        "tradeoff", help="wall time, peak memory and error of each model on a ladder of "
                         "discretisations (Pareto table and plot)")
    add_scene_arguments(p)
    p.add_argument("--out", type=Path, default=None,
                   help="folder for tradeoff.csv, tradeoff.json, tradeoff.png and the cached "
                        "rungs in cases/ (default out/tradeoff-SCENE)")
    p.add_argument("--repeats", type=int, default=3,
                   help="timed runs per rung; the median is reported (default 3; rungs slower "
                        "than --single-above run once)")
    p.add_argument("--single-above", type=float, default=20.0, metavar="SECONDS",
                   help="run a rung once when its first run took longer (default 20 s)")
    p.add_argument("--models", nargs="*", default=None,
                   help=f"models to include (default: all with a ladder: {', '.join(LADDERS)})")
    p.add_argument("--max-time", type=float, default=600.0, metavar="SECONDS",
                   help="stop climbing a model's ladder after a rung slower than this "
                        "(default 600 s)")
    add_engine_arguments(p, "recompute (and re-time) cached rungs")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..models import MODELS
    from ..studies.tradeoff import pareto_table, tradeoff, write_outputs

    scene = load_scene(args.scene, args.overrides)
    names = args.models or [m for m in LADDERS if m in MODELS]
    unknown = [m for m in names if m not in LADDERS or m not in MODELS]
    if unknown:
        raise InputError(f"--models {' '.join(unknown)}: no ladder or not registered; "
                         f"available: {', '.join(m for m in LADDERS if m in MODELS)}")
    if args.repeats < 1:
        raise InputError(f"--repeats {args.repeats}: must be >= 1")
    out = args.out or Path("out") / f"tradeoff-{scene.name}"
    with engine_from_args(args, "tradeoff") as engine:
        doc = tradeoff(scene, names, out / "cases", engine=engine, repeats=args.repeats,
                       single_above=args.single_above, max_time=args.max_time)
    write_outputs(doc, out)
    print(pareto_table(doc))
    print(f"written to {out}/")
    return 0 if all(r["converged"] for r in doc["rows"]) else 1
