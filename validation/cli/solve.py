"""``pillar-xval solve``: run one model on one scene."""

from __future__ import annotations

from pillar_xval.scenes import load_scene

from ..registry import check_options, model_names, scene_defaults
from ._args import (add_choice_arguments, add_model_argument, add_output_arguments,
                    add_refinement_arguments, add_scene_arguments, add_threads_argument,
                    check_out, not_converged, number, print_json, refuse_inapplicable)

# What `solve --out DIR` writes (result.json last: its presence means the folder is whole).
OUTPUTS = ("elements.csv", "pillars.csv", "pressure.png", "fields.vtu", "fields.json",
           "result.json")


def add_parser(sub) -> None:
    from ..registry import MODELS

    models = "; ".join(f"{m.name}: {m.summary}" for m in MODELS.values())
    p = sub.add_parser(
        "solve", help="solve one scene with one model",
        description="Solve one scene with one model and print a summary (or, with --json, "
                    "the result as one JSON document).  A model option that the chosen "
                    f"model does not take is refused.  Models: {models}.")
    add_scene_arguments(p)
    add_model_argument(p, model_names(), help_text="model to run (default bem, the dense "
                                                   "boundary-element solver)")
    add_refinement_arguments(p, ladder=False)
    add_choice_arguments(p)
    add_request_arguments(p)
    add_threads_argument(p)
    add_output_arguments(p, "folder for result.json, element and pillar CSVs, pressure.png "
                            "(and fields.vtu for the FEM)",
                         "print the result as exactly one JSON document")
    p.set_defaults(func=run)


def add_request_arguments(p) -> None:
    """--tolerance, --quantities, --budget: the planner's request, for ``--model auto`` only
    (as ``plan`` takes them; refused for any other model)."""
    p.add_argument("--tolerance", type=number(0.0, 1.0, open_lo=True), default=None,
                   metavar="REL", help="auto: relative error allowed on each quantity "
                                       "(default 0.01 = 1 %%)")
    p.add_argument("--quantities", default=None, metavar="Q,Q",
                   help="auto: comma-separated among F_T, sigma0, a, A (default F_T,sigma0)")
    p.add_argument("--budget", type=number(0.0, None, open_lo=True), default=None,
                   metavar="SECONDS", help="auto: leave out candidates predicted slower than "
                                           "this")


def model_options(args) -> dict:
    """The model options the user gave (None: the model's default)."""
    from ..registry import option_vocabulary

    return {k: getattr(args, k) for k in option_vocabulary()
            if getattr(args, k, None) is not None}


def run(args) -> int:
    refuse_inapplicable(args, [args.model])
    options = model_options(args)
    if args.model == "auto":  # the request checked before the scene is read or solved
        from ..planner.plan import DEFAULT_QUANTITIES, DEFAULT_TOLERANCE, check_request

        tolerance, quantities, budget = check_request(
            options.get("tolerance", DEFAULT_TOLERANCE),
            options.get("quantities", ",".join(DEFAULT_QUANTITIES)), options.get("budget"))
        options.update(tolerance=tolerance, quantities=list(quantities))
        if budget is not None:
            options["budget"] = budget
    scene = load_scene(args.scene, args.overrides)
    options = scene_defaults(args.model, scene, options)
    check_options(args.model, options, "", scene)
    vtu_path = None
    if args.out is not None:
        from ..output.report import clear_outputs

        check_out(args.out)
        clear_outputs(args.out, OUTPUTS, "solve")
        vtu_path = args.out / "fields.vtu"  # models with volume fields write them
    result = _solve(args.model, scene, options, vtu_path)
    if result.diagnostics.get("pillars") == "hooke":
        from ..planner.plan import hooke_note

        note = hooke_note(scene)
        if note:
            result.diagnostics["notes"] = [*result.diagnostics.get("notes", []), note]
    if args.out is not None:
        from ..output.report import write_solve_report

        write_solve_report(result, args.out)
    if args.json:
        print_json(result.to_dict())
    else:
        print(result.summary())
        planned = result.diagnostics.get("plan")
        if planned:
            print(f"auto: chose {planned['choice']['label']}: {planned['reason']}")
        if args.out is not None:
            print(f"written to {args.out}/")
    if result.converged:
        return 0
    return not_converged("solve", [f"{result.model}: "
                                   f"{result.diagnostics.get('message', 'no message')}"])


def _solve(model: str, scene, options: dict, vtu_path=None):
    """Run the model, with progress lines inside a long solve when the model reports them."""
    from ..engine import SolveProgress
    from ..registry import run_model

    with SolveProgress(f"solve {model}") as progress:
        return run_model(model, scene, vtu_path=vtu_path, progress=progress, **options)
