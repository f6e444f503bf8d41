"""``pillar-xval curve``: the loading curve of one scene under rising forces or indentations
(:mod:`validation.studies.curve`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from pillar_xval.scenes import InputError, SceneError, scene_loader

from ..registry import MODELS, model_names
from ._args import (add_choice_arguments, add_engine_arguments, add_levels_argument,
                    add_models_argument, add_output_arguments, add_refinement_arguments,
                    add_scene_arguments, check_out, engine_from_args, number, print_json,
                    refuse_inapplicable, study_status)

MAX_LOADS = 100
DEFAULT_MODELS = ("bem",)
# The load options: flag, the scene key it sets, its unit.
LOADS = {"forces_uN": ("--forces-uN", "load.force_uN", "uN"),
         "indentations_um": ("--indentations-um", "load.indentation_um", "um")}


def _loads(option: str):
    """An argparse type: comma-separated decimal numbers > 0, rising, at most MAX_LOADS; the
    text of each is kept (it becomes the scene's key as the user wrote it)."""
    one = number(0.0, None, open_lo=True)

    def parse(text: str) -> list[tuple[float, str]]:
        items = [t.strip() for t in text.split(",")]
        if not text.strip() or "" in items:
            raise argparse.ArgumentTypeError(f"{text!r}: expected comma-separated numbers "
                                             "such as 1,2,5,10")
        if len(items) > MAX_LOADS:
            raise argparse.ArgumentTypeError(f"{len(items)} loads, at most {MAX_LOADS}")
        values = [(one(t), t) for t in items]
        for (before, b), (after, a) in zip(values, values[1:]):
            if after <= before:
                raise argparse.ArgumentTypeError(f"{a} after {b}: the loads must rise")
        return values

    parse.__name__ = f"{option} list"
    return parse


def add_parser(sub) -> None:
    p = sub.add_parser(
        "curve", help="the loading curve: each model at rising forces or indentations "
                      "(curve.csv, curve.json, curve.png)",
        description="Solve one scene at each of a sequence of loads, given forces "
                    "(--forces-uN) or indentations (--indentations-um), with each model, on "
                    "the study engine (cached, resumable).  Writes curve.csv (one row per "
                    "model and load: force, indentation, contact radius, real contact area, "
                    "centre pressure, pillars in contact, converged; SI), curve.png (F-zeta, "
                    "a-F, A-F, sigma0-F, with the Hertz and single-pillar closed forms, each "
                    "model's uncertainty band over --levels refinements, and --data's "
                    "measured points) and curve.json.")
    add_scene_arguments(p)
    group = p.add_mutually_exclusive_group(required=True)
    for dest, (flag_text, _, unit) in LOADS.items():
        what = "forces" if unit == "uN" else "indentations"
        group.add_argument(flag_text, dest=dest, type=_loads(flag_text), default=None,
                           metavar="X,Y,...",
                           help=f"the {what} in {unit}, comma-separated and rising (at most "
                                f"{MAX_LOADS}); give this or the other load option")
    add_models_argument(p, model_names(), f"default {','.join(DEFAULT_MODELS)}")
    add_refinement_arguments(p, ladder=True)
    add_choice_arguments(p)
    add_levels_argument(p, 1, 1, 8, "refinement levels per model and load (2 or more: the "
                                     "uncertainty band of each point; 3 or more: a GCI)")
    p.add_argument("--data", type=Path, default=None, metavar="FILE.csv",
                   help="measured points to overlay: a CSV with a header row, force_uN and "
                        "any of indentation_um, contact_radius_um, real_contact_area_um2 "
                        "(# starts a comment line); checked before anything is solved")
    add_output_arguments(p, "report folder (default out/curve-SCENE)")
    add_engine_arguments(p, "recompute cached cases")
    p.set_defaults(func=run)


def _scenes(args, loads, flag_text: str, key: str) -> list:
    """The scene at each load; a refused load names the option and its value."""
    load = scene_loader(args.scene)
    scenes = []
    for _, text in loads:
        try:
            scenes.append(load([*args.overrides, f"{key}={text}"]))
        except SceneError as exc:
            message = str(exc).replace(f"--set {key}={text}: ", "")
            raise InputError(f"{flag_text} {text}: {message}") from None
    return scenes


def run(args) -> int:
    from ..output.report import clear_outputs
    from ..studies._ladder import check_ladder
    from ..studies.curve import OUTPUTS, curve_study, read_data, write_outputs

    models = args.models or list(DEFAULT_MODELS)
    refuse_inapplicable(args, models)
    coarsest = {}
    for model in models:
        ladder = MODELS[model].ladder
        if ladder is None:
            continue
        value = getattr(args, ladder.option, None)
        if value is not None:
            coarsest[ladder.option] = value
        if args.levels >= 2:
            check_ladder(model, args.levels, value)
    options = {k: getattr(args, k) for k in ("cells", "contact", "device", "pillars",
                                             "precision") if getattr(args, k, None) is not None}
    data = read_data(args.data) if args.data is not None else None
    dest = next(d for d in LOADS if getattr(args, d) is not None)
    flag_text, key, _ = LOADS[dest]
    scenes = _scenes(args, getattr(args, dest), flag_text, key)
    out = check_out(args.out or Path("out") / f"curve-{scenes[0].name}")
    clear_outputs(out, OUTPUTS, "curve")
    with engine_from_args(args, "curve") as engine:
        doc = curve_study(scenes, models, out / "cases", engine=engine, levels=args.levels,
                          coarsest=coarsest, options=options, data=data,
                          base=scene_loader(args.scene)(args.overrides))
    names = write_outputs(doc, out)
    if args.json:
        print_json(doc)
    else:
        print(curve_table(doc))
        print(f"written to {out}/ ({', '.join(names)})")
    failed = [(2 if r["input_error"] else 3, f"{r['model']} at {r['load']:.6g}: {r['error']}")
              for r in doc["rows"] if "error" in r]
    unconverged = [f"{r['model']} at {r['load']:.6g}: {r['message']}" for r in doc["rows"]
                   if "error" not in r and not r["converged"]]
    return study_status("curve", failed, unconverged)


def curve_table(doc: dict) -> str:
    """The curve as a table in display units (µm, µN, kPa), each band beside its value where
    levels gave one (none on the load given: it is the same on every level)."""
    given = "total_force_N" if doc["control"] == "force" else "indentation_m"
    columns = (("F [uN]", "total_force_N", 1e6), ("zeta [um]", "indentation_m", 1e6),
               ("a [um]", "contact_radius_m", 1e6), ("A [um^2]", "real_contact_area_m2", 1e12),
               ("sigma0 [kPa]", "centre_pressure_Pa", 1e-3))
    width = 18 if doc["levels"] >= 2 else 13
    head = f"{'model':<16}" + "".join(f"{c[0]:>{width}}" for c in columns) + \
        f"{'pillars':>9}{'floor [uN]':>12}  converged"
    lines = [head, "-" * len(head)]
    for r in doc["rows"]:
        if "error" in r:
            lines.append(f"{r['model']:<16}failed: {r['error']}")
            continue
        cells = []
        for _, attr, factor in columns:
            band = r.get("bands", {}).get(attr) if attr != given else None
            text = f"{r[attr] * factor:.5g}" + ("" if band is None else
                                                f" ±{band * factor:.2g}")
            cells.append(f"{text:>{width}}")
        lines.append(f"{r['model']:<16}{''.join(cells)}{r['pillars_in_contact']:>9}"
                     f"{r.get('floor_force_N', 0.0) * 1e6:>12.5g}  {r['converged']}")
    for model, falls in doc["falls"].items():
        lines += [f"{model}: {line}" for line in falls]
    unit, factor = ("uN", 1e6) if doc["control"] == "force" else ("um", 1e6)
    for model, t in (doc.get("transitions") or {}).items():
        if t:
            lines.append(f"{model}: touches the floor between the loads "
                         f"{t['suspended_load'] * factor:.5g} and {t['mixed_load'] * factor:.5g} "
                         f"{unit} (suspended -> mixed; `pillar-xval onset` finds the point)")
    return "\n".join(lines)
