"""``pillar-xval onset``: the indentation and force at which the lens first touches the floor
between the pillars (:mod:`validation.studies.onset`)."""

from __future__ import annotations

from pathlib import Path

from pillar_xval.scenes import load_scene

from ..registry import model_names
from ._args import (add_choice_arguments, add_engine_arguments, add_model_argument,
                    add_output_arguments, add_refinement_arguments, add_scene_arguments,
                    check_out, engine_from_args, not_converged, number, print_json,
                    refuse_inapplicable)
from .solve import model_options


def add_parser(sub) -> None:
    from ..studies.onset import DEFAULT_RTOL

    p = sub.add_parser(
        "onset", help="where the lens first touches the floor between the pillars "
                      "(onset.json)",
        description="Bisection on a model's solves under indentations (cached, resumable) "
                    "for the indentation and the force at which the lens first touches the "
                    "floor between the pillars, the suspended-to-mixed transition: "
                    "onset_indentation_m and onset_force_N with their brackets in "
                    "onset.json.  The scene's own load is replaced.")
    add_scene_arguments(p)
    add_model_argument(p, model_names(), "bem-fft", "a model that includes the floor "
                                                    "(default bem-fft)")
    add_refinement_arguments(p, ladder=False)
    add_choice_arguments(p)
    p.add_argument("--rtol", type=number(0.0, 0.5, open_lo=True), default=DEFAULT_RTOL,
                   help=f"the bracket's width over the indentation (default {DEFAULT_RTOL:g})")
    add_output_arguments(p, "report folder (default out/onset-SCENE)")
    add_engine_arguments(p, "recompute cached cases")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..output.report import clear_outputs
    from ..studies.onset import OUTPUTS, onset_study, write_outputs

    refuse_inapplicable(args, [args.model])
    scene = load_scene(args.scene, args.overrides)
    out = check_out(args.out or Path("out") / f"onset-{scene.name}")
    clear_outputs(out, OUTPUTS, "onset")
    with engine_from_args(args, "onset") as engine:
        doc = onset_study(scene, args.model, out / "cases", options=model_options(args),
                          engine=engine, rtol=args.rtol)
    write_outputs(doc, out)
    if args.json:
        print_json(doc)
    else:
        lo, hi = doc["bracket_indentation_m"]
        flo, fhi = doc["bracket_force_N"]
        print(f"{doc['model']} on {scene.name}: the floor is first touched at zeta = "
              f"{doc['onset_indentation_m'] * 1e6:.6g} um ({doc['onset_over_height']:.4g} h; "
              f"bracket [{lo * 1e6:.6g}, {hi * 1e6:.6g}] um), F = "
              f"{doc['onset_force_N'] * 1e6:.6g} uN (bracket [{flo * 1e6:.6g}, "
              f"{fhi * 1e6:.6g}] uN); {len(doc['solves'])} solves")
        print(f"written to {out}/ ({', '.join(OUTPUTS)})")
    if not doc["converged"]:
        return not_converged("onset", [f"{s['indentation_m']:.6g} m" for s in doc["solves"]
                                       if not s["converged"]])
    return 0
