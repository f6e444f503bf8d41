"""``pillar-xval compare``: the BEM (elastic pillars by default on elastic ones, or the paper's
Hooke spring) against FEM (elastic pillars) on one scene, with each model's numerical
uncertainty beside every difference and a verdict against a stated tolerance
(:mod:`validation.studies.compare`)."""

from __future__ import annotations

from pathlib import Path

from pillar_xval.scenes import InputError, load_scene

from ..registry.options import BOTH
from ..studies.compare import BEM, FEM_COARSEST, FEM_MODELS, OUTPUTS
from ._args import (add_engine_arguments, add_levels_argument,
                    add_models_argument, add_output_arguments, add_refinement_arguments,
                    add_scene_arguments, check_out, engine_from_args, not_converged, print_json,
                    pillar_models_type, refuse_inapplicable, scene_pillars)


def add_parser(sub) -> None:
    """Register ``compare`` on the CLI's subparsers."""
    p = sub.add_parser(
        "compare", help="BEM against FEM (elastic pillars), each with its GCI uncertainty",
        description="Solve one scene with the dense BEM (--pillars: elastic or Hooke-spring "
                    "pillars) and an FEM "
                    "with elastic pillars (the axisymmetric model on a flat scene or one pillar "
                    "alone, fem-3d on a lattice scene), each on --levels refinements, and set "
                    "every difference beside the two models' numerical uncertainty (GCI).  "
                    "Writes report.json, summary.md, profiles.png/.csv, the finest FEM fields "
                    "(VTU) and a 3D render of its stress.  --pillars both runs the FEM once "
                    "and both BEMs (Hooke and elastic pillars): a three-way table and profile "
                    "plot.")
    add_scene_arguments(p)
    add_models_argument(p, (BEM, *FEM_MODELS),
                        "bem and one FEM; default bem and fem-axisym where it applies (flat "
                        "scene, or Phi below Phi_S), fem-3d otherwise")
    add_refinement_arguments(p, ladder=True, families=("elements_per_diameter", "mesh_size"),
                             defaults={"elements_per_diameter": 11,
                                       "mesh_size": " or ".join(
                                           f"{v:g} ({m})" for m, v in FEM_COARSEST.items())})
    p.add_argument("--pillars", type=pillar_models_type, default=None, metavar="MODEL",
                   help="the BEM's pillar model: 'hooke', the paper's uniformly shortening "
                        "spring, 'elastic', the whole pillar's top compliance (from a "
                        "Fourier-mode FEM of one pillar, cached; the default on elastic "
                        f"pillars, hooke on rigid ones), or '{BOTH}' (or "
                        "'hooke,elastic'): both BEMs against the one FEM, a three-way table "
                        "and profile plot")
    add_levels_argument(p, 3, 2, 8, "refinement levels of each model (3 or more give an "
                                    "observed order and a GCI)")
    add_output_arguments(p, "report folder (default out/compare/<scene>)")
    p.add_argument("--no-render", action="store_true", help="skip the pyvista render")
    add_engine_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    """Run both models, write the report folder, print the table; exit 1 if a run did not
    converge."""
    from ..studies.compare import check_options, compare_study, fem_model_for, table_text, title

    fem = _chosen_fem(args.models)
    refuse_inapplicable(args, [BEM, fem or FEM_MODELS[0]])
    check_options(args.levels, args.mesh_size, args.elements_per_diameter, fem or FEM_MODELS[0])
    scene = load_scene(args.scene, args.overrides)
    fem = fem or fem_model_for(scene)
    check_options(args.levels, args.mesh_size, args.elements_per_diameter, fem)
    pillars = scene_pillars(args.pillars, scene) or "hooke"
    if not isinstance(pillars, str) and len(pillars) == 1:  # one BEM: a two-way table
        pillars = pillars[0]
    out = check_out(args.out or Path("out") / "compare" / scene.name)
    with engine_from_args(args, "compare") as engine:
        report = compare_study(scene, out, engine=engine, levels=args.levels,
                               mesh_size=args.mesh_size,
                               elements_per_diameter=args.elements_per_diameter,
                               render=not args.no_render, fem_model=fem,
                               pillars=pillars)
    if args.json:
        print_json(report)
    else:
        ref = report["closed_form"]["name"]
        r_label = "d/2" if report["scene"].get("pillars") else "a_Hertz"
        print(title(scene, fem, report["pillars"]))
        print(table_text(report["rows"], ref, r_label, report["levels"],
                         None if scene.is_flat else report["pillars"]))
        print(f"render: {report['render']}")
        written = [name for name in OUTPUTS if (out / name).exists()]
        print(f"report: {out}/ ({', '.join(written)})")
    if report["converged"]:
        return 0
    return not_converged("compare", report["not_converged"])


def _chosen_fem(models) -> str | None:
    """The FEM named in ``--models`` (None: chosen by the scene); the list must be bem and
    one FEM."""
    if models is None:
        return None
    fems = [m for m in models if m in FEM_MODELS]
    if BEM not in models or len(fems) != 1 or len(models) != 2:
        raise InputError(f"--models {','.join(models)}: compare takes bem and one FEM "
                         f"({' or '.join(FEM_MODELS)})")
    return fems[0]
