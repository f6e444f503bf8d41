"""``pillar-xval sweep SPEC.toml --out DIR``: a grid of scenes x models on the engine, into
one table (CSV and Parquet).  The spec format is documented in
:mod:`validation.studies.sweep`; ``validation/examples/sweep-phi-zeta.toml`` is an example."""

from __future__ import annotations

from pathlib import Path

from ._args import (add_engine_arguments, add_output_arguments, check_out, engine_from_args,
                    failure_status, print_json, study_status)


def add_parser(sub) -> None:
    p = sub.add_parser("sweep", help="a grid of scenes x models (spec file) into one table, "
                                     "resumable",
                       description="Run every case of a sweep spec (TOML) on the engine and "
                                   "write one row per case to DIR/NAME.csv and NAME.parquet.  "
                                   "The spec names the scene, the grid and each model's "
                                   "options (validation/examples/sweep-phi-zeta.toml).")
    p.add_argument("spec", type=Path, help="sweep spec (TOML)")
    add_output_arguments(p, "folder for the table and the cached cases (default "
                            "out/sweep-NAME)",
                         "print exactly one JSON document: the table's rows (with --dry-run: "
                         "the cost estimate)")
    p.add_argument("--dry-run", action="store_true",
                   help="print the case count and a cost estimate; solve nothing")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..output.report import clear_outputs
    from ..studies.sweep import (Sweep, run_sweep_cases, table_rows,
                                 write_table)

    sweep = Sweep.from_toml(args.spec)
    out = args.out or Path("out") / f"sweep-{sweep.name}"
    say = (lambda *a: None) if args.json else print
    if args.dry_run:
        return _dry_run(args, sweep, out, say)
    cases, skipped = sweep.cases()
    for point, why in skipped:
        say(f"skipped {point}: {why}")
    check_out(out)
    clear_outputs(out, (f"{sweep.name}.csv", f"{sweep.name}.parquet"), "sweep")
    with engine_from_args(args, "sweep") as engine:
        pairs = run_sweep_cases(sweep, out, engine=engine)
    rows = table_rows(sweep, pairs)
    paths = write_table(rows, out, sweep.name)
    failed = [(failure_status(o.error), f"{c.case.describe()} at {c.point}: {o.error}")
              for c, o in pairs if not o.ok]
    unconverged = [f"{c.case.describe()} at {c.point}" for c, o in pairs
                   if o.ok and not o.result.converged]
    if args.json:
        print_json({"table": [str(p) for p in paths], "rows": rows})
    else:
        print(f"{len(rows)} cases ({len(failed)} failed, {len(unconverged)} not converged); "
              f"table: {', '.join(str(p) for p in paths)}")
    return study_status("sweep", failed, unconverged)


# A dry run checks every point of a grid up to this many; beyond, a seeded sample of
# DRY_RUN_SAMPLE points (a million-point grid once took 9 minutes to say nothing).
DRY_RUN_EXACT = 20_000
DRY_RUN_SAMPLE = 2_000


def _dry_run(args, sweep, out: Path, say) -> int:
    """Count the cases, the cached ones and the time of the rest, without solving."""
    import random

    from ..studies.sweep import estimate_cost

    workers = engine_from_args(args).parallel  # the options checked as a run checks them
    total = sweep.point_count()
    indices = None
    if total > DRY_RUN_EXACT:
        indices = sorted(random.Random(0).sample(range(total), DRY_RUN_SAMPLE))
    cases, skipped = sweep.cases(indices)
    cache = out / "cases"
    cost = estimate_cost(cases, cache if cache.is_dir() else None, workers)
    scale = 1.0 if indices is None else total / len(indices)
    doc = {**cost, "skipped": len(skipped), "points": total,
           "sampled_points": None if indices is None else len(indices)}
    if indices is not None:  # the sample's figures, scaled to the whole grid
        doc.update(cases=round(cost["cases"] * scale), cached=round(cost["cached"] * scale),
                   skipped=round(len(skipped) * scale), cpu_seconds=cost["cpu_seconds"] * scale,
                   wall_seconds=cost["wall_seconds"] * scale)
        for m in doc["per_model"].values():
            m.update(cases=round(m["cases"] * scale), cached=round(m["cached"] * scale),
                     seconds=m["seconds"] * scale)
    if args.json:
        print_json(doc)
        return 0
    if indices is None:
        for point, why in skipped:
            say(f"skipped {point}: {why}")
    about = "" if indices is None else "~"
    print(f"{about}{doc['cases']} cases ({about}{doc['cached']} already in {cache}), "
          f"{about}{doc['skipped']} grid points skipped, of {total} points")
    for model, m in doc["per_model"].items():
        print(f"  {model:<11} {about}{m['cases']:>6} cases, {about}{m['cached']:>6} cached, "
              f"~{m['seconds']:.3g} s of one core")
    print(f"estimated: ~{doc['wall_seconds']:.3g} s on {workers} worker(s) (the planner's "
          "cost fits)")
    if indices is not None:
        print(f"(from a seeded sample of {len(indices)} of the {total} points: a dry run "
              f"checks every point up to {DRY_RUN_EXACT})")
    return 0
