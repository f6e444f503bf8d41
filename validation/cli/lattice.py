"""``pillar-xval lattice``: the paper's Hooke BEM and the elastic-pillar BEM against the
elastic-pillar 3D FEM over Phi x E_p/E_l (:mod:`validation.studies.lattice`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._args import (add_engine_arguments, add_output_arguments, check_out,
                    engine_from_args, number, positive_numbers, print_json, study_status)


# --paper-scenes grid: every point of the Phi x E_p/E_l grid but E_p = E_l (the same scene).
GRID = "grid"


def paper_pairs(given, phis, ratios):
    """The E_s = E_p scenes that --paper-scenes names: its pairs, every grid point but
    E_p/E_l = 1 for ``grid``, or None (the study's default)."""
    if given == GRID:
        return [(phi, r) for phi in phis for r in ratios if r != 1.0]
    return given


def _pairs(text: str) -> list[tuple[float, float]]:
    """``PHI:RATIO,...`` (or ``none``, or ``grid``) for --paper-scenes."""
    if text.strip().lower() == "none":
        return []
    if text.strip().lower() == "grid":
        return GRID
    phi, ratio = number(0.0, open_lo=True), number(0.0, open_lo=True)
    out = []
    for item in (v.strip() for v in text.split(",") if v.strip()):
        parts = item.split(":")
        if len(parts) != 2:
            raise argparse.ArgumentTypeError(f"{item!r}: expected PHI:RATIO, such as 0.2:10")
        out.append((phi(parts[0]), ratio(parts[1])))
    return out


def add_parser(sub) -> None:
    from ..studies.lattice import PAPER_SCENES, PHIS, RATIOS, ZETA_UM

    p = sub.add_parser(
        "lattice", help="multi-pillar cross-validation: Hooke and elastic-pillar BEMs against "
                        "fem-3d over Phi x E_p/E_l, each difference beside both models' "
                        "uncertainty, the elastic BEM's targets judged",
        description="The multi-pillar cross-validation: on Table 1 scenes at zeta = 0.3 um "
                    "(--zeta-um; the Phi x E_p/E_l grid with E_s = E_l, and a few scenes at the paper's "
                    "E_s = E_p), the Hooke-pillar BEM (bem-fft), the elastic-pillar BEM "
                    "(bem-fft, pillars = elastic) and the elastic-pillar FEM (fem-3d) each "
                    "climb three refinement levels; F_T, sigma0, a and A are compared as "
                    "Richardson estimates beside both GCI bands, the per-pillar forces as "
                    "FEM/BEM ratios by lattice ring, and the elastic BEM is judged against its "
                    "targets (F_T 1 %, sigma0 3 %, ring forces 2 %, the centre pillar's top "
                    "profile 5 %, or both bands where wider).  Writes lattice.csv, rings.csv, "
                    "profile.csv, lattice.png, profiles.png, summary.md and lattice.json; "
                    "resumes after an interruption (cases in DIR/cases).")
    p.add_argument("--surface-fractions", type=positive_numbers, default=list(PHIS),
                   metavar="PHI,...",
                   help=f"surface fractions (default {','.join(f'{v:g}' for v in PHIS)})")
    p.add_argument("--ratios", type=positive_numbers, default=list(RATIOS), metavar="R,...",
                   help=f"E_p/E_l values (default {','.join(f'{v:g}' for v in RATIOS)})")
    p.add_argument("--paper-scenes", type=_pairs, default=None, metavar="PHI:R,...",
                   help="scenes at the paper's convention E_s = E_p, as Phi:E_p/E_l pairs, "
                        "'grid' (every grid point but E_p/E_l = 1, which is the same scene) "
                        "or 'none' (default: those of "
                        + ",".join(f"{a:g}:{b:g}" for a, b in PAPER_SCENES)
                        + " whose Phi and ratio are in the grid)")
    p.add_argument("--zeta-um", type=number(0.0, open_lo=True), default=ZETA_UM,
                   metavar="ZETA",
                   help=f"the indentation of every scene, micrometres (default {ZETA_UM:g}; "
                        "the scene's own checks give its allowed range)")
    p.add_argument("--quick", action="store_true",
                   help="two coarse levels per model (minutes, not an hour): a smoke run")
    add_output_arguments(p, "report folder (default out/lattice)")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..output.report import clear_outputs
    from ..studies import lattice as study

    pairs = paper_pairs(args.paper_scenes, args.surface_fractions, args.ratios)
    points = study.default_points(args.surface_fractions, args.ratios, pairs, args.zeta_um)
    for point in points:
        point.scene()  # refuse a bad Phi or ratio before any solve, naming it
    levels = ((study.QUICK_FEM_LEVELS, study.QUICK_BEM_LEVELS, study.QUICK_DENSE_LEVELS,
               study.QUICK_FFT_RUNGS) if args.quick else
              (study.FEM_LEVELS, study.BEM_LEVELS, study.DENSE_LEVELS, study.FFT_RUNGS))
    out = check_out(args.out or Path("out") / "lattice")
    clear_outputs(out, study.OUTPUTS, "lattice")
    with engine_from_args(args, "lattice") as engine:
        report = study.lattice_study(out, engine=engine, points=points, fem_levels=levels[0],
                                     bem_levels=levels[1], dense_levels=levels[2],
                                     fft_rungs=levels[3])
    names = study.write_report(report, out)
    if args.json:
        print_json(report)
    else:
        print(study.table_text(report))
        print(f"report: {out}/ ({', '.join(names)})")
    failed = [(r["exit"], f"{r['label']}: {r['status']}")
              for r in report["rows"] if r["status"].startswith("failed")]
    unconverged = [r["label"] for r in report["rows"] if r["status"] == "not converged"]
    return study_status("lattice", failed, unconverged)
