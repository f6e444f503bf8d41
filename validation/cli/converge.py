"""``pillar-xval converge``: a model on N refinement levels, observed order, Richardson
estimate and GCI per quantity (F_T, sigma0, a, A), with a log-log plot, CSV and JSON."""

from __future__ import annotations

from pathlib import Path

from pillar_xval.scenes import load_scene

from ..registry import ladders
from ._args import (add_choice_arguments, add_engine_arguments, add_levels_argument,
                    add_model_argument, add_output_arguments, add_refinement_arguments,
                    add_scene_arguments, check_out, engine_from_args, not_converged, print_json,
                    refuse_inapplicable, scene_pillars)


def add_parser(sub) -> None:
    """Register ``converge`` on the CLI's subparsers."""
    p = sub.add_parser(
        "converge", help="grid convergence study of one model: order, Richardson estimate, GCI",
        description="Solve a scene with one model on N refinement levels (each halving the "
                    "element size of the last, from the coarsest given by the model's "
                    "refinement option) and report, per quantity, the observed order, the "
                    "Richardson estimate and the GCI band (Roache; Celik et al. 2008).")
    add_scene_arguments(p)
    add_model_argument(p, sorted(ladders()), help_text="model to refine (default bem)")
    add_refinement_arguments(p, ladder=True, defaults={
        ladder.option: ladder.coarsest for ladder in ladders().values()})
    add_choice_arguments(p, ["pillars"])
    add_levels_argument(p, 3, 2, 8, "refinement levels (3 or more give an observed order)")
    add_output_arguments(p, "report folder (default out/converge/<scene>-<model>)")
    add_engine_arguments(p, "recompute cached levels")
    p.set_defaults(func=run)


def _fixed_options(args, scene) -> dict:
    """The model's options that every level shares (the ladder sets the refined one): the
    pillar model, by default the scene's (:func:`validation.registry.scene_defaults`)."""
    from ..registry import scene_defaults

    scene_pillars(args.pillars, scene)  # the elastic pillar on a flat scene is refused
    given = {} if args.pillars is None else {"pillars": args.pillars}
    return scene_defaults(args.model, scene, given)


def run(args) -> int:
    """Study, write the report folder, print the table; exit 1 if a level did not converge."""
    from ..studies._ladder import check_ladder
    from ..studies.converge import OUTPUTS, converge_study, study_table, write_report
    from ..output.report import clear_outputs

    refuse_inapplicable(args, [args.model])
    option = ladders()[args.model].option
    coarsest = getattr(args, option, None)
    check_ladder(args.model, args.levels, coarsest)
    scene = load_scene(args.scene, args.overrides)
    fixed = _fixed_options(args, scene)
    out = check_out(args.out or Path("out") / "converge" / f"{scene.name}-{args.model}")
    clear_outputs(out, OUTPUTS, "converge")
    with engine_from_args(args, "converge") as engine:
        data = converge_study(args.model, scene, args.levels, out / "cases",
                              coarsest=coarsest, engine=engine,
                              options=fixed)
    names = write_report(data, out)
    if args.json:
        print_json({k: v for k, v in data.items() if k != "results"})
    else:
        print(f"{data['label']} on {scene.name}: {args.levels} levels of "
              f"{data['ladder']['option']}")
        print(study_table(data))
        print(f"report: {out}/ ({', '.join(names)})")
    if data["all_converged"]:
        return 0
    return not_converged("converge", [
        f"level {lv['level'] + 1} ({option}={lv['value']}): {lv['message']}"
        for lv in data["levels"] if not lv["converged"]])
