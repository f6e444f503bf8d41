"""``pillar-xval converge``: a model on N refinement levels, observed order, Richardson
estimate and GCI per quantity (F_T, sigma0, a, A), with a log-log plot, CSV and JSON.

Also home of the two pieces the other studies share: the per-model refinement ladder
(:data:`LADDERS`; adding a model is one entry) and :func:`run_cached`, which writes each
finished case at once under a key derived from scene + model + discretisation, so that a
rerun resumes and skips finished work.  The key does not know the code: after changing a
model, pass ``--fresh`` (or delete the ``cases/`` folder) to recompute.
"""

from __future__ import annotations

import csv
import hashlib
import importlib
import inspect
import io
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from scenes import ContactResult, Scene, load_scene, write_atomic

from .models import MODELS, model_names, run_model
from .verification import study

# (key, ContactResult attribute, unit, label): the quantities every study reports.
QUANTITIES = (
    ("F_T", "total_force_N", "N", "total force F_T"),
    ("sigma0", "centre_pressure_Pa", "Pa", "centre pressure sigma_0"),
    ("a", "contact_radius_m", "m", "contact radius a"),
    ("A", "real_contact_area_m2", "m^2", "real contact area A"),
)


@dataclass(frozen=True)
class Ladder:
    """How a model is refined: option ``option`` takes ``coarsest * factor**k`` on level k,
    rounded by ``kind``: ``"float"`` (none), ``"int"`` (nearest integer) or ``"odd"``
    (``round((coarsest + 1) factor**k) - 1``, which keeps an odd count odd for factor 2, so a
    centre element stays centred); the cell size is ``h = value**h_power`` (relative)."""

    option: str
    coarsest: float
    factor: float
    kind: str
    h_power: float
    fixed: dict = field(default_factory=dict)
    h_meaning: str = ""

    def value(self, k: int, coarsest: float | None = None):
        """Value of the refined option on level ``k`` (0 = coarsest)."""
        v0 = self.coarsest if coarsest is None else coarsest
        if self.kind == "odd":
            return int(round((v0 + 1) * self.factor**k)) - 1
        if self.kind == "int":
            return int(round(v0 * self.factor**k))
        return float(v0 * self.factor**k)

    def size(self, value) -> float:
        """Relative cell size h of an option value."""
        return float(value) ** self.h_power

    def options(self, k: int, coarsest: float | None = None) -> dict:
        """Model options of level ``k``: the fixed ones and the refined one."""
        return {**self.fixed, self.option: self.value(k, coarsest)}


LADDERS: dict[str, Ladder] = {
    # BEM: square elements across a pillar (or Hertz contact) diameter, 11, 23, 47, ...;
    # 'covered' cells carry the true disk area, so the sequence converges smoothly.
    "bem": Ladder("elements_per_diameter", 11, 2.0, "odd", -1.0, {"cells": "covered"},
                  "element side / diameter = 1/P"),
    # FFT BEM: grid cells across a pillar diameter, 32, 64, 128, ...
    "bem-fft": Ladder("cells_per_diameter", 32, 2.0, "int", -1.0, {},
                      "cell side / diameter = 1/N"),
    # FEM: the mesh builder's single size parameter scales every element size.
    "fem-axisym": Ladder("mesh_size", 1.0, 0.5, "float", 1.0, {}, "mesh_size (relative)"),
}


def ladder_for(model: str) -> Ladder:
    """The refinement ladder of ``model``; ValueError (one line) for a model without one."""
    if model not in LADDERS:
        raise ValueError(f"--model {model!r}: no refinement ladder; known: "
                         f"{', '.join(sorted(LADDERS))}")
    return LADDERS[model]


# --- cached runs ------------------------------------------------------------------------
def case_key(model: str, scene: Scene, options: dict) -> str:
    """16 hex digits of sha256 over the scene's physics (not its name), the model and its
    options: equal keys mean equal computations."""
    physics = {k: v for k, v in scene.to_dict().items() if k != "name"}
    text = json.dumps({"scene": physics, "model": model, "options": options},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def case_stem(model: str, scene: Scene, options: dict) -> str:
    """Readable, unique file stem of a case: model, options, then :func:`case_key`."""
    opts = "-".join(f"{k}={v}" for k, v in sorted(options.items()))
    return f"{model}-{opts}-{case_key(model, scene, options)}".replace("/", "_")


def vtu_file(cache_dir: Path, stem: str) -> Path:
    """The VTU of a case: ``<stem>.fields.vtu`` (a model may write a ``<stem>.fields.json``
    sidecar beside it; the cached result is ``<stem>.json``)."""
    return Path(cache_dir) / f"{stem}.fields.vtu"


def _solver(model: str):
    module, function, _ = MODELS[model]
    return getattr(importlib.import_module(module), function)


def accepts_vtu(model: str) -> bool:
    """Whether the model's function takes ``vtu_path`` (it writes its fields as VTU)."""
    try:
        return "vtu_path" in inspect.signature(_solver(model)).parameters
    except (ImportError, ValueError, TypeError):
        return False


def run_cached(model: str, scene: Scene, options: dict, cache_dir: Path, *,
               vtu: bool = False, fresh: bool = False, tag: str = "") -> tuple[ContactResult, bool]:
    """Run ``model`` on ``scene`` unless ``cache_dir`` already holds this case.

    Returns the result and whether it came from the cache.  With ``vtu`` and a model that can
    write one, the VTU sits beside the JSON (:func:`vtu_file`).  A progress line goes to stderr.
    """
    if model not in MODELS:
        raise ValueError(f"--model {model!r}: unknown; available: {', '.join(model_names())}")
    stem = case_stem(model, scene, options)
    path = Path(cache_dir) / f"{stem}.json"
    vtu_path = vtu_file(cache_dir, stem)
    want_vtu = vtu and accepts_vtu(model)
    if not fresh and path.exists() and (not want_vtu or vtu_path.exists()):
        try:
            result = ContactResult.from_json(path.read_text())
        except (ValueError, TypeError, KeyError) as exc:  # an older schema: recompute
            progress(tag, f"{path.name} unreadable ({exc}); recomputing")
        else:
            progress(tag, f"{model} {_fmt_opts(options)}: cached ({path.name})")
            return result, True
    progress(tag, f"{model} {_fmt_opts(options)}: running ...")
    t0 = time.perf_counter()
    if want_vtu:
        vtu_path.parent.mkdir(parents=True, exist_ok=True)
        kwargs = {k: v for k, v in options.items() if k in MODELS[model][2] and v is not None}
        result = _solver(model)(scene, **kwargs, vtu_path=vtu_path)
    else:
        result = run_model(model, scene, **options)
    write_atomic(path, result.to_json())
    progress(tag, f"{model} {_fmt_opts(options)}: done in {time.perf_counter() - t0:.1f} s"
             + ("" if result.converged else "  (NOT CONVERGED)"))
    return result, False


# Errors that make one case of a sweep fail without stopping the others (a SceneError is a
# ValueError; the FEM's SolveError and a broken process pool are RuntimeErrors).
CASE_ERRORS = (ArithmeticError, RuntimeError, ValueError)


def run_many(model: str, cases: list[tuple[Scene, dict, str]], cache_dir: Path, *,
             workers: int = 1, fresh: bool = False) -> list[tuple]:
    """:func:`run_cached` over ``cases`` (scene, options, progress tag), on ``workers``
    processes (fork; each case is written by its worker at once, so an interrupted sweep
    resumes).  Returns, in input order, (result, cached) or (exception, False) for a case
    that failed with one of :data:`CASE_ERRORS`.
    """
    out: list = [None] * len(cases)
    if workers <= 1 or len(cases) < 2:
        for i, (scene, options, tag) in enumerate(cases):
            try:
                out[i] = run_cached(model, scene, options, cache_dir, fresh=fresh, tag=tag)
            except CASE_ERRORS as exc:
                out[i] = (exc, False)
        return out
    import concurrent.futures as cf
    import multiprocessing as mp

    ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else None
    with cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
        futures = {pool.submit(run_cached, model, scene, options, cache_dir, fresh=fresh,
                               tag=tag): i for i, (scene, options, tag) in enumerate(cases)}
        for future in cf.as_completed(futures):
            try:
                out[futures[future]] = future.result()
            except CASE_ERRORS as exc:
                out[futures[future]] = (exc, False)
    return out


def progress(tag: str, text: str) -> None:
    """One progress line on stderr, prefixed by ``[tag]``."""
    print(f"[{tag or 'pillar-xval'}] {text}", file=sys.stderr, flush=True)


def _fmt_opts(options: dict) -> str:
    return " ".join(f"{k}={v}" for k, v in sorted(options.items()))


def quantity_values(result: ContactResult) -> dict[str, float]:
    """The :data:`QUANTITIES` of a result, SI, by key."""
    return {key: float(getattr(result, attr)) for key, attr, _, _ in QUANTITIES}


# --- the command -------------------------------------------------------------------------
def add_parser(sub) -> None:
    """Register ``converge`` on the CLI's subparsers."""
    from .cli import add_scene_arguments

    p = sub.add_parser("converge", help="grid convergence study of one model: order, "
                                        "Richardson estimate, GCI")
    add_scene_arguments(p)
    p.add_argument("--model", default="fem-axisym", choices=model_names(),
                   help="model to refine (default fem-axisym)")
    p.add_argument("--levels", type=int, default=3, metavar="N",
                   help="refinement levels, >= 2 (3 or more give an observed order); default 3")
    p.add_argument("--coarsest", type=float, default=None, metavar="VALUE",
                   help="value of the refined option on the coarsest level (bem: elements per "
                        "diameter, default 11; fem-axisym: mesh_size, default 1.0)")
    p.add_argument("--out", type=Path, default=None,
                   help="report folder (default out/converge/<scene>-<model>)")
    p.add_argument("--fresh", action="store_true", help="recompute cached levels")
    p.set_defaults(func=run)


def converge_study(model: str, scene: Scene, levels: int, cache_dir: Path, *,
                   coarsest: float | None = None, fresh: bool = False, tag: str = "converge",
                   vtu_finest: bool = False) -> dict:
    """Run ``levels`` refinements (resuming from ``cache_dir``) and study each quantity.

    Returns a JSON-ready dict with the ladder, one row per level (coarse to fine) and, per
    quantity, the :func:`validation.verification.study` dict.  ``vtu_finest`` asks for the
    VTU of the finest level (its path is in ``levels[-1]['vtu']``).
    """
    if not 2 <= levels <= 8:
        raise ValueError(f"--levels {levels}: allowed range is 2..8")
    ladder = ladder_for(model)
    rows, results = [], []
    for k in range(levels):
        opts = ladder.options(k, coarsest)
        finest = k == levels - 1
        result, cached = run_cached(model, scene, opts, cache_dir, fresh=fresh,
                                    vtu=vtu_finest and finest, tag=f"{tag} {k + 1}/{levels}")
        vtu_path = vtu_file(cache_dir, case_stem(model, scene, opts))
        rows.append({"level": k, "options": opts, "value": opts[ladder.option],
                     "h": ladder.size(opts[ladder.option]), "cached": cached,
                     "converged": bool(result.converged), "wall_time_s": result.wall_time_s,
                     "vtu": str(vtu_path) if vtu_path.exists() else None,
                     **quantity_values(result)})
        results.append(result)
    h = [r["h"] for r in rows]
    studies = {key: study(h, [r[key] for r in rows]) for key, *_ in QUANTITIES}
    return {"model": model, "scene": scene.to_dict(),
            "ladder": {"option": ladder.option, "h_meaning": ladder.h_meaning,
                       "fixed": ladder.fixed},
            "levels": rows, "studies": studies,
            "all_converged": all(r["converged"] for r in rows),
            "results": results}


def study_table(data: dict) -> str:
    """Plain-text table of the per-quantity GCI results."""
    lines = [f"{'quantity':<8}{'finest':>13}{'':5}{'order p':>9}{'Richardson':>14}"
             f"{'GCI_fine':>10}{'GCI23/r^pGCI12':>16}  status"]
    for key, _, unit, _ in QUANTITIES:
        g = data["studies"][key]["gci"]
        lines.append(
            f"{key:<8}{g['f'][0]:>13.6g} {unit:<4}"
            + f"{_num(g['order'], '.3f'):>9}{_num(g['f_exact'], '.7g'):>14}"
            + f"{_num(None if g['gci_fine'] is None else 100 * g['gci_fine'], '.3g', '%'):>10}"
            + f"{_num(g['asymptotic_ratio'], '.3f'):>16}  {g['status']}")
    return "\n".join(lines)


def _num(x, fmt: str, suffix: str = "") -> str:
    return "-" if x is None else f"{x:{fmt}}{suffix}"


def levels_csv(data: dict) -> str:
    """CSV of the levels (coarse to fine): option value, h and every quantity (SI)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["level", data["ladder"]["option"], "h", *(f"{k}_{u}" for k, _, u, _ in QUANTITIES),
                "converged", "wall_time_s"])
    for r in data["levels"]:
        w.writerow([r["level"], r["value"], repr(r["h"]), *(repr(r[k]) for k, *_ in QUANTITIES),
                    r["converged"], f"{r['wall_time_s']:.4g}"])
    return buf.getvalue()


def gci_csv(data: dict) -> str:
    """CSV of the per-quantity verification results (GCI as fractions, SI values)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    cols = ["order", "f_exact", "gci_fine", "gci_coarse", "uncertainty", "asymptotic_ratio",
            "fallback_uncertainty", "status"]
    w.writerow(["quantity", "unit", "f_finest", *cols, "lsq_order", "lsq_r_squared"])
    for key, _, unit, _ in QUANTITIES:
        s = data["studies"][key]
        g = s["gci"]
        w.writerow([key, unit, repr(g["f"][0]), *("" if g[c] is None else g[c] for c in cols),
                    "" if s["lsq"]["order"] is None else s["lsq"]["order"],
                    "" if s["lsq"]["r_squared"] is None else s["lsq"]["r_squared"]])
    return buf.getvalue()


def run(args) -> int:
    """``pillar-xval converge``: study, write the report folder, print the table; exit 1 if a level
    did not converge."""
    scene = load_scene(args.scene, args.overrides)
    out = args.out or Path("out") / "converge" / f"{scene.name}-{args.model}"
    data = converge_study(args.model, scene, args.levels, out / "cases",
                          coarsest=args.coarsest, fresh=args.fresh)
    data.pop("results")
    write_atomic(out / "converge.json", json.dumps(data, indent=2, allow_nan=False))
    write_atomic(out / "levels.csv", levels_csv(data))
    write_atomic(out / "gci.csv", gci_csv(data))
    from .plots_xval import plot_convergence

    plot_convergence(data, out / "convergence.png")
    print(f"{args.model} on {scene.name}: {args.levels} levels of {data['ladder']['option']}")
    print(study_table(data))
    print(f"report: {out}/ (converge.json, levels.csv, gci.csv, convergence.png)")
    return 0 if data["all_converged"] else 1
