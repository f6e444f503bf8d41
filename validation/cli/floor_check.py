"""``pillar-xval floor-check``: the elastic-pillar BEM against the FEMs past the pillar tops,
where the lens rests on the floor between the pillars (:mod:`validation.studies.floor_check`)."""

from __future__ import annotations

from pathlib import Path

from ._args import (add_engine_arguments, add_output_arguments, check_out, engine_from_args,
                    positive_numbers, print_json, study_status)


def add_parser(sub) -> None:
    from ..studies.floor_check import POINTS

    p = sub.add_parser(
        "floor-check", help="the floor between the pillars: the elastic-pillar bem-fft against "
                            "fem-axisym (one pillar) and fem-3d (lattices), targets judged",
        description="On one pillar (fem-axisym) and four lattices (fem-3d), each at an "
                    "indentation where the lens touches the floor between the pillars, the "
                    "elastic-pillar bem-fft and the FEM each climb a refinement ladder; F_T, "
                    "the floor's share of the load, the floor contact area and the onset "
                    "indentation (a bisection at every level) are compared as Richardson "
                    "estimates against the targets (1 %, 2 points, 5 %, 2 %, or both GCI "
                    "bands where wider).  Writes floor_check.md, floor_check.csv and "
                    "floor_check.json; resumes after an interruption (cases in DIR/cases).")
    p.add_argument("--surface-fractions", type=positive_numbers, default=None,
                   metavar="PHI,...",
                   help="only the study's scenes with these surface fractions (default all: "
                        + ",".join(f"{q.surface_fraction:g}" for q in POINTS) + ")")
    p.add_argument("--quick", action="store_true",
                   help="two coarse levels per model (a smoke run, minutes)")
    p.add_argument("--maps", action="store_true",
                   help="also draw each lattice's floor contact, bem-fft's cells over fem-3d's "
                        "vertices at the finest levels (DIR/maps/*.png; both solved again)")
    add_output_arguments(p, "report folder (default out/floor-check)")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from pillar_xval.scenes import InputError

    from ..output.report import clear_outputs
    from ..studies import floor_check as study

    points = list(study.POINTS)
    if args.surface_fractions is not None:
        known = {q.surface_fraction for q in points}
        unknown = [v for v in args.surface_fractions if v not in known]
        if unknown or not args.surface_fractions:
            raise InputError(f"--surface-fractions {','.join(f'{v:g}' for v in unknown)}: "
                             "allowed values are "
                             + ",".join(f"{v:g}" for v in sorted(known)))
        points = [q for q in points if q.surface_fraction in args.surface_fractions]
    out = check_out(args.out or Path("out") / "floor-check")
    clear_outputs(out, study.OUTPUTS, "floor-check")
    with engine_from_args(args, "floor-check") as engine:
        report = study.floor_check_study(out, engine=engine, points=points, quick=args.quick)
    names = study.write_report(report, out)
    if args.maps:
        names += _maps(study, points, report, out, args.quick)
    if args.json:
        print_json(report)
    else:
        print(study.summary_markdown(report), end="")
        print(f"report: {out}/ ({', '.join(names)})")
    failed = [(r["exit"], f"{r['label']}: {r['status']}") for r in report["rows"]
              if "exit" in r]
    unconverged = [r["label"] for r in report["rows"] if r["status"] == "not converged"]
    return study_status("floor-check", failed, unconverged)


def _maps(study, points, report, out: Path, quick: bool) -> list[str]:
    """The floor-contact overlay of every lattice whose row solved (:mod:`..studies.floor_maps`),
    progress on stderr; the written files' names relative to ``out``."""
    import sys

    from ..studies.floor_maps import floor_map, map_name

    ok = {r["label"] for r in report["rows"] if "exit" not in r}
    written = []
    for point in points:
        if point.single or point.label not in ok:
            continue
        bem, fem = (study.levels_of(kind, point, quick)[-1] for kind in ("bem", "fem"))
        print(f"floor-check: the contact map of {point.label} (bem-fft N = {bem}, fem-3d "
              f"{fem:g})", file=sys.stderr, flush=True)
        name = Path("maps") / map_name(point.label)
        floor_map(point, bem, fem, out / name)
        written.append(str(name))
    return written
