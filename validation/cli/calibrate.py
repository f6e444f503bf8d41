"""``pillar-xval calibrate``: measure the planner's error and cost models
(:mod:`validation.studies.calibrate`)."""

from __future__ import annotations

import shutil
from pathlib import Path

from ._args import add_engine_arguments, check_out, engine_from_args, print_json


def _paths(text: str) -> list:
    import argparse

    paths = [Path(v.strip()) for v in text.split(",") if v.strip()]
    if not paths:
        raise argparse.ArgumentTypeError(f"{text!r}: expected one or more lattice.json "
                                         "files, comma-separated")
    return paths


def add_parser(sub) -> None:
    p = sub.add_parser(
        "calibrate", help="measure the planner's error and cost models (convergence ladders, "
                          "Gecit grid, closed forms, FEM truncation) on seeded scenes",
        description="Run the calibration studies on the engine (resumable) and write "
                    "error_models.json, cost_models.json and calibration.json to --out; "
                    "--install copies the two models into the package's data folder, where "
                    "`pillar-xval plan` reads them.")
    p.add_argument("--out", type=Path, default=Path("out") / "calibrate",
                   help="folder for the data files, the report and the cached cases "
                        "(default out/calibrate)")
    p.add_argument("--install", action="store_true",
                   help="copy error_models.json and cost_models.json into validation/planner/data")
    p.add_argument("--lattice", type=_paths, default=None, metavar="LATTICE_JSON[,...]",
                   help="lattice.json of `pillar-xval lattice` (several, comma-separated: "
                        "studies at different --zeta-um, which give the tables a zeta axis): "
                        "the Hooke pillar's error and the elastic-pillar BEMs' in lattices, "
                        "and fem-3d's discretisation, measured against fem-3d "
                        "(without it the Gecit grid's single-pillar error and a hand bound "
                        "stand in)")
    p.add_argument("--lattice-only", action="store_true",
                   help="with --lattice: replace only the lattice tables (Hooke, elastic BEM) of the "
                        "installed "
                        "error_models.json (seconds; the other studies are not re-run)")
    p.add_argument("--quick", action="store_true",
                   help="a handful of scenes per study (a smoke test, not a calibration)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON document (the files written and the provenance)")
    add_engine_arguments(p, "recompute cached cases")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..studies.calibrate import calibrate, load_lattice, write_data
    from ..planner.tables import data_dir

    lattice = None if args.lattice is None else load_lattice(args.lattice)
    check_out(args.out)
    if args.lattice_only:
        return _lattice_only(args, lattice)
    with engine_from_args(args, "calibrate") as engine:
        doc = calibrate(args.out, engine, quick=args.quick, lattice=lattice)
    names = write_data(doc, args.out)
    installed = []
    if args.install:
        for name in ("error_models.json", "cost_models.json"):
            installed.append(str(shutil.copyfile(args.out / name, data_dir() / name)))
    prov = doc["errors"]["provenance"]
    if args.json:
        print_json({"written": [str(args.out / n) for n in names], "installed": installed,
                    "provenance": prov})
        return 0
    print(f"calibration: {len(doc['errors']['tables'])} error tables, "
          f"{len(doc['costs']['models'])} cost fits from {prov['scenes']} scenes in "
          f"{prov['wall_time_s']:.0f} s")
    for t in doc["errors"]["tables"]:
        loo = ", ".join(f"{q} {_median(v):.2f}" for q, v in t["loo"].items())
        opt = ",".join(f"{k}={v}" for k, v in t["option"].items())
        print(f"  {t['kind']:<15}{t['component']:<15}{'/'.join(t['models']):<26}"
              f"{opt:<24}{'/'.join(t['regimes']):<13}{len(t['points']):>4} pts  "
              f"LOO median {loo}")
    for m, f in doc["costs"]["models"].items():
        print(f"  cost {m:<12} {f['samples']:>4} runs, ln-time residual {f['rms']:.2f}")
    print(f"written to {args.out}/ ({', '.join(names)})"
          + (f"; installed {', '.join(installed)}" if installed else ""))
    return 0


def _median(values) -> float:
    import statistics

    known = [v for v in values if v is not None]
    return statistics.median(known) if known else float("nan")


def _lattice_only(args, lattice) -> int:
    import json

    from pillar_xval.scenes import InputError

    from ..studies.calibrate import relattice, write_document
    from ..planner.tables import data_dir

    if lattice is None:
        raise InputError("--lattice-only: needs --lattice LATTICE_JSON")
    installed = data_dir() / "error_models.json"
    doc = relattice(json.loads(installed.read_text()), lattice,
                    ",".join(map(str, args.lattice)))
    args.out.mkdir(parents=True, exist_ok=True)
    write_document(args.out / "error_models.json", doc)
    done = [str(args.out / "error_models.json")]
    if args.install:
        done.append(str(shutil.copyfile(args.out / "error_models.json", installed)))
    if args.json:
        print_json({"written": done, "lattice_rows": len(lattice["rows"])})
    else:
        print(f"lattice tables (Hooke, elastic BEMs, fem-3d) from "
              f"{','.join(map(str, args.lattice))} ({len(lattice['rows'])} lattices): "
              + ", ".join(done))
    return 0
