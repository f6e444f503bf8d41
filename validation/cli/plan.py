"""``pillar-xval plan``: which model a scene needs for a tolerance, with predicted errors,
time and memory (:mod:`validation.planner`)."""

from __future__ import annotations


from pathlib import Path

from pillar_xval.scenes import ScopeError, load_scene

from ._args import (add_engine_arguments, add_scene_arguments, add_threads_argument,
                    check_out, engine_from_args, integer, number, print_json)

# A plan slower than this prints its step on stderr ("[plan] predicting candidate 12 of 30:
# ..."): the first plan of a process reads the tables and imports the FEMs' memory
# estimates, which took 13 s on a cold machine without a word.
PROGRESS_AFTER_S = 1.0


def add_parser(sub) -> None:
    _add_plan(sub)
    _add_validate(sub)


def _add_plan(sub) -> None:
    p = sub.add_parser(
        "plan", help="the cheapest model predicted within a tolerance for a scene",
        description="Predict every candidate model's error per quantity (measured "
                    "discretisation and model errors), time and memory on this machine, and "
                    "choose the cheapest within --tolerance for every requested quantity. "
                    "`solve --model auto` runs the choice.")
    add_scene_arguments(p)
    p.add_argument("--tolerance", type=number(0.0, 1.0, open_lo=True), default=0.01,
                   metavar="REL",
                   help="relative error allowed on each quantity (default 0.01 = 1 %%)")
    p.add_argument("--quantities", default="F_T,sigma0", metavar="Q,Q",
                   help="comma-separated among F_T, sigma0, a, A (default F_T,sigma0)")
    p.add_argument("--budget", type=number(0.0, None, open_lo=True), default=None,
                   metavar="SECONDS", help="leave out candidates predicted slower than this; "
                                           "when none is left, one line naming the budget "
                                           "and the cheapest candidate's time, exit 2")
    p.add_argument("--json", action="store_true", help="print the plan as one JSON document")
    add_threads_argument(p)  # the plan's times are for a solve on that many threads
    p.set_defaults(func=run)


def run(args) -> int:
    """Print the plan; exit 2 (``ScopeError``, one line: the reason) when it has no choice:
    no candidate within ``--budget`` (the line names the budget and the cheapest candidate's
    predicted time), or none that can run the scene.  With --json the plan is printed
    first."""
    from ..planner.plan import check_request, plan, plan_text

    from ..engine import SolveProgress

    tolerance, quantities, budget = check_request(args.tolerance, args.quantities, args.budget)
    scene = load_scene(args.scene, args.overrides)
    with SolveProgress("plan", after_s=PROGRESS_AFTER_S) as progress:
        p = plan(scene, tolerance, quantities, budget, progress=progress)
    if args.json:
        print_json(p)
    elif p["choice"] is not None:
        print(plan_text(p))
    if p["choice"] is None:
        raise ScopeError(p["reason"])
    return 0


def _add_validate(sub) -> None:
    from ..studies.validate_plan import (DEFAULT_LATTICE, DEFAULT_SCENES,
                                              FEM3D_FINEST_MAX_S, MAX_LATTICE, MAX_SCENES,
                                              MAX_SEED, VALIDATION_SEED)

    p = sub.add_parser(
        "validate-plan", help="validate the planner on seeded scenes against the toolkit's "
                              "best references",
        description="Plan each scene of a seeded set the calibration never saw (the paper's "
                    "ranges, a stiff substrate, flat scenes, and lattices with sigma0 "
                    "requested whose reference is fem-3d's Richardson estimate over "
                    "mesh_size 2.83, 2, 1.41, where every candidate, hand-entered ones "
                    "included, is judged), run the plan, the reference and every cheaper "
                    "candidate on the engine (resumable), and report how often the planned "
                    "model is within tolerance (target 95 %) and within 2x of the cheapest "
                    "candidate that was (target 90 %), with every miss and its reasons; "
                    "exit 1 when a target is missed.  Prints the time the planner's cost "
                    "models predict for the run first (--dry-run: only that).")
    p.add_argument("--out", type=Path, default=Path("out") / "validate-plan",
                   help="report folder and cached cases (default out/validate-plan)")
    p.add_argument("--tolerance", type=number(0.0, 1.0, open_lo=True), default=0.01,
                   metavar="REL", help="relative error allowed on each quantity (default 0.01)")
    p.add_argument("--quantities", default="F_T,sigma0", metavar="Q,Q",
                   help="comma-separated among F_T, sigma0, a, A (default F_T,sigma0; the "
                        "lattice-sigma0 scenes add sigma0)")
    p.add_argument("--scenes", type=integer(1, MAX_SCENES), default=DEFAULT_SCENES,
                   metavar="N",
                   help=f"scenes in all, 1 to {MAX_SCENES} (default {DEFAULT_SCENES}): the "
                        "--lattice-scenes, then the rest split 35 : 6 : 4 between the "
                        "paper's family, a stiff substrate and flat scenes (4 at most)")
    p.add_argument("--lattice-scenes", type=integer(0, MAX_LATTICE), default=DEFAULT_LATTICE,
                   metavar="N",
                   help=f"lattice scenes with sigma0 requested and fem-3d as the reference, "
                        f"0 to {MAX_LATTICE} and at most --scenes (default {DEFAULT_LATTICE}): "
                        f"several pillars touch, E_p/E_l in [0.1, 1e3], fem-3d's finest level "
                        f"fits the memory and is predicted under {FEM3D_FINEST_MAX_S:g} s")
    p.add_argument("--seed", type=integer(0, MAX_SEED), default=VALIDATION_SEED,
                   metavar="N",
                   help=f"seed of the scene draws, 0 to {MAX_SEED} but not the "
                        f"calibration's (default {VALIDATION_SEED})")
    p.add_argument("--dry-run", action="store_true",
                   help="plan the scenes and print the estimated time only; nothing runs")
    p.add_argument("--json", action="store_true", help="print the totals as one JSON document")
    add_engine_arguments(p, "recompute cached cases")
    p.set_defaults(func=run_validate)


def run_validate(args) -> int:
    from ..planner.plan import check_request
    from ..studies.validate_plan import (check_options, estimate, estimate_text,
                                              prepare, summary_text, validate_planner,
                                              validation_scenes, write_outputs)

    tolerance, quantities, _ = check_request(args.tolerance, args.quantities)
    check_options(args.scenes, args.lattice_scenes, args.seed)
    if not args.dry_run:
        check_out(args.out)
    scenes = validation_scenes(args.scenes, args.lattice_scenes, args.seed)
    prepared = prepare(scenes, tolerance, quantities)
    est = estimate(prepared)
    if args.dry_run:
        if args.json:
            print_json(est)
        else:
            print(estimate_text(est))
        return 0
    if not args.json:
        print(estimate_text(est), flush=True)
    with engine_from_args(args, "validate-plan") as engine:
        doc = validate_planner(args.out, engine, tolerance=tolerance, quantities=quantities,
                               prepared=prepared)
    doc["totals"]["estimate"] = est
    names = write_outputs(doc, args.out)
    if args.json:
        print_json(doc["totals"])
    else:
        print(summary_text(doc))
        print(f"written to {args.out}/ ({', '.join(names)})")
    return 0 if doc["totals"]["targets_met"] else 1
