"""``pillar-xval lattice``: the paper's Hooke BEM against the elastic-pillar 3D FEM over Phi x
E_p/E_l (:mod:`validation.studies.lattice`)."""

from __future__ import annotations

from pathlib import Path

from ._args import (add_engine_arguments, add_output_arguments, check_out,
                    engine_from_args, number, print_json, study_status)


def _numbers(text: str) -> list[float]:
    parse = number(0.0, open_lo=True)
    return [parse(v.strip()) for v in text.split(",") if v.strip()]


def add_parser(sub) -> None:
    from ..studies.lattice import PHIS, RATIOS

    p = sub.add_parser(
        "lattice", help="multi-pillar cross-validation: Hooke BEM against fem-3d over Phi x "
                        "E_p/E_l, each difference beside both models' uncertainty",
        description="The first multi-pillar cross-validation: on Table 1 scenes at zeta = "
                    "0.3 um with E_s = E_l, the Hooke-pillar BEM (bem-fft) and the "
                    "elastic-pillar FEM (fem-3d) each climb three refinement levels; F_T, "
                    "sigma0, a and A are compared as Richardson estimates beside both GCI "
                    "bands, and the per-pillar forces as FEM/BEM ratios by lattice ring.  "
                    "Writes lattice.csv, rings.csv, lattice.png, summary.md and lattice.json; "
                    "resumes after an interruption (cases in DIR/cases).")
    p.add_argument("--surface-fractions", type=_numbers, default=list(PHIS), metavar="PHI,...",
                   help=f"surface fractions (default {','.join(f'{v:g}' for v in PHIS)})")
    p.add_argument("--ratios", type=_numbers, default=list(RATIOS), metavar="R,...",
                   help=f"E_p/E_l values (default {','.join(f'{v:g}' for v in RATIOS)})")
    p.add_argument("--quick", action="store_true",
                   help="two coarse levels per model (minutes, not an hour): a smoke run")
    add_output_arguments(p, "report folder (default out/lattice)")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..output.report import clear_outputs
    from ..studies import lattice as study

    points = study.grid(args.surface_fractions, args.ratios)
    for point in points:
        point.scene()  # refuse a bad Phi or ratio before any solve, naming it
    levels = ((study.QUICK_FEM_LEVELS, study.QUICK_BEM_LEVELS) if args.quick
              else (study.FEM_LEVELS, study.BEM_LEVELS))
    out = check_out(args.out or Path("out") / "lattice")
    clear_outputs(out, study.OUTPUTS, "lattice")
    with engine_from_args(args, "lattice") as engine:
        report = study.lattice_study(out, engine=engine, points=points, fem_levels=levels[0],
                                     bem_levels=levels[1])
    names = study.write_report(report, out)
    if args.json:
        print_json(report)
    else:
        print(study.table_text(report))
        print(f"report: {out}/ ({', '.join(names)})")
    failed = [(r["exit"], f"Phi={r['surface_fraction']:g} Ep/El={r['ratio']:g}: {r['status']}")
              for r in report["rows"] if r["status"].startswith("failed")]
    unconverged = [f"Phi={r['surface_fraction']:g} Ep/El={r['ratio']:g}"
                   for r in report["rows"] if r["status"] == "not converged"]
    return study_status("lattice", failed, unconverged)
