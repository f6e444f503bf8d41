"""``pillar-xval tradeoff``: wall time, peak memory and error of each model on its ladder
(:mod:`validation.studies.tradeoff`)."""

from __future__ import annotations

from pathlib import Path

from pillar_xval.scenes import load_scene

from ..registry import MODELS, ladders
from ._args import (add_choice_arguments, add_engine_arguments, add_models_argument,
                    add_output_arguments, add_refinement_arguments, add_scene_arguments, check_out,
                    engine_from_args, integer, not_converged, number, print_json,
                    refuse_inapplicable, scene_pillars)


def _expensive() -> list[str]:
    """Models that join only when named (their declaration: minutes per rung)."""
    return [m for m in ladders() if MODELS[m].expensive]


def _default_models() -> list[str]:
    return [m for m in ladders() if not MODELS[m].expensive]


def add_parser(sub) -> None:
    p = sub.add_parser(
        "tradeoff", help="wall time, peak memory and error of each model on a ladder of "
                         "discretisations (Pareto table and plot)",
        description="Solve one scene with each model on its ladder of resolutions, timing "
                    "every rung (median of --repeats runs) and measuring its peak memory; "
                    "errors are against a Richardson reference.  Writes tradeoff.csv, "
                    "tradeoff.json and tradeoff.png (error against time, Pareto front "
                    "marked, points labelled by their resolution).")
    add_scene_arguments(p)
    add_models_argument(p, list(ladders()),
                        f"default: {','.join(_default_models())}; "
                        f"{', '.join(_expensive())} joins when named (minutes per rung)")
    add_refinement_arguments(p, ladder=True)
    add_choice_arguments(p, ["pillars"])
    p.add_argument("--levels", type=integer(1, 12), default=None, metavar="N",
                   help="rungs per model, from the coarsest (default: the ladder's rungs; "
                        "at least 3 from a given coarsest level); allowed [1, 12]")
    add_output_arguments(p, "folder for tradeoff.csv, tradeoff.json, tradeoff.png and the "
                            "cached rungs in cases/ (default out/tradeoff-SCENE)")
    p.add_argument("--repeats", type=integer(1, 100), default=3, metavar="N",
                   help="timed runs per rung; the median is reported (default 3; rungs slower "
                        "than --single-above run once); allowed [1, 100]")
    p.add_argument("--single-above", type=number(0.0), default=20.0, metavar="SECONDS",
                   help="run a rung once when its first run took longer (default 20 s)")
    p.add_argument("--max-time", type=number(0.0, open_lo=True), default=600.0,
                   metavar="SECONDS", help="stop climbing a model's ladder after a rung slower "
                                           "than this (default 600 s); > 0")
    add_engine_arguments(p, "recompute (and re-time) cached rungs")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..studies.tradeoff import OUTPUTS, check_options, pareto_table, tradeoff, write_outputs
    from ..output.report import clear_outputs

    names = args.models or _default_models()
    refuse_inapplicable(args, names)
    coarsest = {k: getattr(args, k) for k in (MODELS[m].ladder.option for m in names)
                if getattr(args, k, None) is not None}
    options = dict(coarsest=coarsest, levels=args.levels, repeats=args.repeats,
                   single_above=args.single_above, max_time=args.max_time)
    check_options(names, **options)
    scene = load_scene(args.scene, args.overrides)
    # The pillar model of the BEMs (by default the scene's): the elastic one is measured
    # against the elastic pillar's reference (its physics), never against the Hooke BEMs'.
    pillars = scene_pillars(args.pillars, scene)
    solver_options = {"pillars": pillars} if pillars else None
    out = check_out(args.out or Path("out") / f"tradeoff-{scene.name}")
    clear_outputs(out, OUTPUTS, "tradeoff")
    with engine_from_args(args, "tradeoff") as engine:
        doc = tradeoff(scene, names, out / "cases", engine=engine, options=solver_options,
                       **options)
    write_outputs(doc, out)
    if args.json:
        print_json(doc)
    else:
        print(pareto_table(doc))
        print(f"written to {out}/")
    missed = [f"{r['model']} {r['option']}={r['level']}: {r.get('message', '')}"
              for r in doc["rows"] if not r["converged"]]
    return not_converged("tradeoff", missed) if missed else 0
