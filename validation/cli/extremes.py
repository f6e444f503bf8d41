"""``pillar-xval extremes``: every model over the corners and edges of the parameter space
(:mod:`validation.studies.extremes`)."""

from __future__ import annotations

from pathlib import Path

from ._args import add_engine_arguments, check_out, engine_from_args, print_json


def add_parser(sub) -> None:
    from ..studies.extremes import model_options

    models = list(model_options())
    p = sub.add_parser(
        "extremes", help="every model over the corners of the parameter space: convergence, "
                         "invariants, time; summary table and heat map",
        description="Run each model on the nominal scene, its edges and the corners of "
                    "E_p/E_l, E_s/E_l (1e-3..1e6), Phi (0.002..0.9), zeta/h (0.0025..0.99), "
                    "R (10 d..1 m) and nu (0, 0.3, 0.4999, 0.5), plus flat scenes; check "
                    "force balance, p >= 0, no interpenetration and F increasing in zeta "
                    "and stiffness.  Resumable (cases cached in OUT/cases).")
    p.add_argument("--out", type=Path, default=Path("out") / "extremes",
                   help="report folder (default out/extremes)")
    p.add_argument("--models", default=",".join(models), metavar="A,B",
                   help=f"comma-separated models (default {','.join(models)})")
    p.add_argument("--quick", action="store_true", help="a handful of corners (smoke test)")
    p.add_argument("--json", action="store_true",
                   help="print the verdict counts per model as one JSON document")
    add_engine_arguments(p, "recompute cached cases")
    p.set_defaults(func=run)


def run(args) -> int:
    from pillar_xval.scenes import InputError

    from ..studies.extremes import model_options, run_extremes
    from ..studies.extremes.report import counts, summary_text, write_outputs

    allowed = list(model_options())
    models = [m.strip() for m in args.models.split(",") if m.strip()]
    bad = [m for m in models if m not in allowed]
    if bad or not models:
        raise InputError(f"--models {args.models}: allowed: {', '.join(allowed)}")
    check_out(args.out)
    with engine_from_args(args, "extremes") as engine:
        doc = run_extremes(args.out, engine, quick=args.quick, models=models)
    names = write_outputs(doc, args.out)
    if args.json:
        print_json(counts(doc))
    else:
        print(summary_text(doc))
        print(f"written to {args.out}/ ({', '.join(names)})")
    broken = [f"{r['corner']} / {r['model']}: {r['status']}" for r in doc["records"]
              if r["status"] in ("fail", "error")]
    if broken:
        import sys

        print(f"pillar-xval extremes: {len(broken)} run(s) broke an invariant or crashed: "
              + "; ".join(broken[:3]) + (" ..." if len(broken) > 3 else ""), file=sys.stderr)
        return 1
    return 0
