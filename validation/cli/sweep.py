"""``pillar-xval sweep SPEC.toml --out DIR``: a grid of scenes x models on the engine, into
one table (CSV and Parquet).  The spec format is documented in
:mod:`validation.studies.sweep`; ``validation/examples/sweep-phi-zeta.toml`` is an example."""

from __future__ import annotations

from pathlib import Path

from ._args import add_engine_arguments, engine_from_args


def add_parser(sub) -> None:
    p = sub.add_parser("sweep", help="a grid of scenes x models (spec file) into one table, "
                                     "resumable",
                       description="Run every case of a sweep spec (TOML) on the engine and "
                                   "write one row per case to DIR/NAME.csv and NAME.parquet.")
    p.add_argument("spec", type=Path, help="sweep spec (TOML)")
    p.add_argument("--out", type=Path, default=None,
                   help="folder for the table and the cached cases (default out/sweep-NAME)")
    p.add_argument("--dry-run", action="store_true",
                   help="print the case count and a cost estimate; solve nothing")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..engine import default_workers
    from ..studies.sweep import Sweep, estimate_cost, run_sweep, write_table

    sweep = Sweep.from_toml(args.spec)
    out = args.out or Path("out") / f"sweep-{sweep.name}"
    cases, skipped = sweep.cases()
    for point, why in skipped:
        print(f"skipped {point}: {why}")
    if args.dry_run:
        workers = 1 if args.executor == "serial" else (args.workers or default_workers())
        cost = estimate_cost(cases, out / "cases", workers)
        print(f"{cost['cases']} cases ({cost['cached']} already in {out / 'cases'}), "
              f"{len(skipped)} grid points skipped")
        for model, m in cost["per_model"].items():
            print(f"  {model:<11} {m['cases']:>6} cases, {m['cached']:>6} cached, "
                  f"~{m['seconds']:.3g} s of one core")
        print(f"estimated: ~{cost['wall_seconds']:.3g} s on {workers} worker(s) "
              f"(rough per-model cost model)")
        return 0
    with engine_from_args(args, "sweep") as engine:
        rows = run_sweep(sweep, out, engine=engine)
    paths = write_table(rows, out, sweep.name)
    failed = [r for r in rows if r["status"] != "ok"]
    unconverged = [r for r in rows if r["status"] == "ok" and not r["converged"]]
    print(f"{len(rows)} cases ({len(failed)} failed, {len(unconverged)} not converged); "
          f"table: {', '.join(str(p) for p in paths)}")
    return 0 if not failed and not unconverged else 1
