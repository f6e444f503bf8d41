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
    from ..studies.sweep import (Sweep, estimate_cost, run_sweep_cases, table_rows,
                                 write_table)

    sweep = Sweep.from_toml(args.spec)
    out = args.out or Path("out") / f"sweep-{sweep.name}"
    cases, skipped = sweep.cases()
    say = (lambda *a: None) if args.json else print
    for point, why in skipped:
        say(f"skipped {point}: {why}")
    if args.dry_run:
        workers = engine_from_args(args).parallel  # the options checked as a run checks them
        cache = out / "cases"
        cost = estimate_cost(cases, cache if cache.is_dir() else None, workers)
        if args.json:
            print_json({**cost, "skipped": len(skipped)})
            return 0
        print(f"{cost['cases']} cases ({cost['cached']} already in {out / 'cases'}), "
              f"{len(skipped)} grid points skipped")
        for model, m in cost["per_model"].items():
            print(f"  {model:<11} {m['cases']:>6} cases, {m['cached']:>6} cached, "
                  f"~{m['seconds']:.3g} s of one core")
        print(f"estimated: ~{cost['wall_seconds']:.3g} s on {workers} worker(s) "
              f"(rough per-model cost model)")
        return 0
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
