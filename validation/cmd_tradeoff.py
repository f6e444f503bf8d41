"""``pillar-xval tradeoff``: what each model's accuracy costs in time and memory.

For every model that has a ladder in :data:`LADDERS` (and is registered in
:mod:`validation.models`), the command solves the scene on each rung of the ladder and
records the wall time (median of ``--repeats``), the peak memory (tracemalloc: numpy arrays
and Python objects; buffers private to C libraries are not seen) and the four compared
quantities F_T, sigma_0, a and A.  The reference of each quantity is a Richardson
extrapolation from the three finest rungs of one model (observed order, Celik et al. 2008);
among models whose extrapolation succeeded, the one with the smallest GCI band is taken.  The
error of every rung is |f - f_ref| / |f_ref|.

Outputs in ``--out``: ``tradeoff.csv`` (one row per model and rung), ``tradeoff.json`` (rows,
references with their orders and bands, scene and versions) and ``tradeoff.png`` (log-log
error against wall time, one panel per quantity, one line per model).

A model joins by one entry in ``LADDERS``: the name of its resolution option and the rungs.

References
----------
.. [1] I. B. Celik et al., J. Fluids Eng. 130 (2008) 078001 (Richardson extrapolation, GCI).
"""

from __future__ import annotations

import csv
import io
import json
import statistics
import sys
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from scenes import load_scene, write_atomic
from scenes.result import package_version

from .report import save_figure


def _per_diameter(level) -> float:
    return 1.0 / level


@dataclass(frozen=True)
class Ladder:
    """Rungs of one model: ``option`` is the keyword of its resolution, ``levels`` coarse to
    fine, ``options`` fixed keywords, ``size`` the representative cell size of a level (any
    unit: only ratios within one model matter; default 1 / level for elements or cells per
    diameter; a mesh-size factor would pass ``size=float``)."""

    option: str
    levels: tuple
    options: tuple = ()
    size: Callable = _per_diameter


# One entry per model.  The FEM refuses scenes with more than one pillar in contact and is
# then skipped with its reason.
LADDERS: dict[str, Ladder] = {
    "bem": Ladder("elements_per_diameter", (5, 7, 9, 11, 15, 21), (("cells", "covered"),)),
    "bem-fft": Ladder("cells_per_diameter", (8, 12, 16, 24, 32, 48, 64)),
    "fem-axisym": Ladder("mesh_size", (4.0, 2.0, 1.0, 0.5), size=float),
}

# Models that solve the same equations share a reference; a model with other physics (the
# elastic pillar of the FEM against the Hooke pillar of the BEM) is measured against its own,
# so that its errors are discretisation errors, not the modelling difference (which
# ``pillar-xval compare`` reports).  On a flat scene every model solves the Hertz problem.
PHYSICS = {"bem": "hooke-pillar", "bem-fft": "hooke-pillar", "fem-axisym": "elastic-pillar"}


def physics_group(model: str, scene) -> str:
    return "half-space" if scene.is_flat else PHYSICS.get(model, model)


QUANTITIES = (("total_force_N", "F_T"), ("centre_pressure_Pa", "sigma0"),
              ("contact_radius_m", "a"), ("real_contact_area_m2", "A"))


def add_parser(sub) -> None:
    from .cli import add_scene_arguments

    p = sub.add_parser(
        "tradeoff", help="wall time, peak memory and error of each model on a ladder of "
                         "discretisations (Pareto table and plot)")
    add_scene_arguments(p)
    p.add_argument("--out", type=Path, default=None,
                   help="folder for tradeoff.csv, tradeoff.json, tradeoff.png "
                        "(default out/tradeoff-SCENE)")
    p.add_argument("--repeats", type=int, default=3,
                   help="timed runs per rung; the median is reported (default 3; rungs slower "
                        "than --single-above run once)")
    p.add_argument("--single-above", type=float, default=20.0, metavar="SECONDS",
                   help="run a rung once when its first run took longer (default 20 s)")
    p.add_argument("--models", nargs="*", default=None,
                   help=f"models to include (default: all with a ladder: {', '.join(LADDERS)})")
    p.add_argument("--max-time", type=float, default=600.0, metavar="SECONDS",
                   help="stop climbing a model's ladder after a rung slower than this "
                        "(default 600 s)")
    p.set_defaults(func=run)


def run(args) -> int:
    from .models import MODELS

    scene = load_scene(args.scene, args.overrides)
    names = args.models or [m for m in LADDERS if m in MODELS]
    unknown = [m for m in names if m not in LADDERS or m not in MODELS]
    if unknown:
        raise ValueError(f"--models {' '.join(unknown)}: no ladder or not registered; "
                         f"available: {', '.join(m for m in LADDERS if m in MODELS)}")
    if args.repeats < 1:
        raise ValueError(f"--repeats {args.repeats}: must be >= 1")
    out = args.out or Path("out") / f"tradeoff-{scene.name}"
    doc = tradeoff(scene, names, repeats=args.repeats, single_above=args.single_above,
                   max_time=args.max_time)
    write_outputs(doc, out)
    print(pareto_table(doc))
    print(f"written to {out}/")
    return 0 if all(r["converged"] for r in doc["rows"]) else 1


def _progress(text: str) -> None:
    print(f"tradeoff: {text}", file=sys.stderr, flush=True)


def measure(solver, scene, kwargs, repeats=3, single_above=20.0):
    """Run ``solver(scene, **kwargs)``: (result, median wall time s, peak traced MB).

    The first run is traced for the peak memory only: tracemalloc slows numpy-heavy code by up
    to 60 % (measured on the dense model), so the times come from untraced runs, at least one;
    a rung slower than ``single_above`` seconds is timed once."""
    tracemalloc.start()
    try:
        start = time.perf_counter()
        result = solver(scene, **kwargs)
        traced = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()
    runs = 1 if traced > single_above else max(1, repeats)
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        solver(scene, **kwargs)
        times.append(time.perf_counter() - start)
    return result, statistics.median(times), peak


def tradeoff(scene, models, repeats=3, single_above=20.0, max_time=600.0,
             ladders=None) -> dict:
    """Solve every rung of every model and attach errors against the Richardson reference."""
    import importlib

    from .models import MODELS

    ladders = ladders or LADDERS
    rows, skipped = [], {}
    for name in models:
        module, function, _ = MODELS[name]
        try:
            solver = getattr(importlib.import_module(module), function)
        except (ImportError, AttributeError) as exc:
            skipped[name] = f"not available ({exc})"
            _progress(f"{name}: skipped, {skipped[name]}")
            continue
        ladder = ladders[name]
        for k, level in enumerate(ladder.levels):
            kwargs = {ladder.option: level, **dict(ladder.options)}
            _progress(f"{name} {ladder.option}={level} ({k + 1}/{len(ladder.levels)})")
            try:
                result, wall, peak = measure(solver, scene, kwargs, repeats, single_above)
            except ValueError as exc:  # includes SceneError: the model refuses this scene
                skipped[name] = f"refused {ladder.option}={level}: {exc}"
                _progress(f"{name}: {skipped[name]}")
                break
            row = {"model": name, "option": ladder.option, "level": level,
                   "h": ladder.size(level), "wall_time_s": wall, "peak_memory_MB": peak,
                   "iterations": result.iterations, "converged": bool(result.converged)}
            for field, short in QUANTITIES:
                row[short] = float(getattr(result, field))
            rows.append(row)
            _progress(f"  {wall:.3g} s, {peak:.0f} MB, F_T = {row['F_T']:.6g} N"
                      + ("" if result.converged else "  NOT CONVERGED"))
            if wall > max_time and k + 1 < len(ladder.levels):
                skipped[name] = f"stopped after {ladder.option}={level} ({wall:.0f} s > " \
                                f"--max-time)"
                _progress(f"{name}: {skipped[name]}")
                break
    for row in rows:
        row["physics"] = physics_group(row["model"], scene)
    references = {group: reference_values([r for r in rows if r["physics"] == group])
                  for group in sorted({r["physics"] for r in rows})}
    for row in rows:
        for _, short in QUANTITIES:
            ref = references[row["physics"]][short]["value"]
            row[f"err_{short}"] = abs(row[short] - ref) / abs(ref) if ref else None
    return {"scene": scene.to_dict(), "models": list(models), "rows": rows,
            "references": references, "skipped": skipped, "repeats": repeats,
            "ladders": {m: {"option": ladders[m].option, "levels": list(ladders[m].levels)}
                        for m in models if m in ladders},
            "version": package_version()}


def reference_values(rows: list) -> dict:
    """Per quantity: the Richardson estimate with the smallest band among the models, or the
    most expensive converged solution when no model's three finest rungs allow an estimate."""
    from .verification import gci_three

    out = {}
    models = sorted({r["model"] for r in rows})
    for _, short in QUANTITIES:
        candidates, per_model = [], {}
        for m in models:
            mine = sorted((r for r in rows if r["model"] == m and r["converged"]),
                          key=lambda r: r["h"])
            if len(mine) < 3:
                continue
            g = gci_three([r["h"] for r in mine[:3]], [r[short] for r in mine[:3]])
            per_model[m] = {"f_exact": g.f_exact, "order": g.order, "band": g.uncertainty,
                            "status": g.status}
            if g.status == "ok" and g.uncertainty is not None:
                candidates.append((g.uncertainty, m, g))
        if candidates:
            band, m, g = min(candidates, key=lambda c: c[0])
            out[short] = {"value": g.f_exact, "model": m, "order": g.order,
                          "band": band, "status": "richardson",
                          "sizes": g.h}
        else:
            # Sizes h of different models are in different units: take the most expensive
            # converged solution, a unit-free stand-in for the most resolved one.
            done = [r for r in rows if r["converged"]]
            finest = max(done, key=lambda r: r.get("wall_time_s", 0.0)) if done else None
            out[short] = {"value": finest[short] if finest else 0.0,
                          "model": finest["model"] if finest else None, "order": None,
                          "band": None,
                          "status": "most expensive solution (no Richardson estimate)",
                          "sizes": [finest["h"]] if finest else []}
        # Every model's own extrapolation: do the models converge to the same answer?
        out[short]["per_model"] = per_model
    return out


CSV_COLUMNS = ("model", "physics", "option", "level", "h", "wall_time_s", "peak_memory_MB", "iterations",
               "converged", "F_T", "sigma0", "a", "A", "err_F_T", "err_sigma0", "err_a",
               "err_A")


def write_outputs(doc: dict, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, extrasaction="ignore")
    writer.writeheader()
    for row in doc["rows"]:
        writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in CSV_COLUMNS})
    write_atomic(out / "tradeoff.csv", buf.getvalue())
    write_atomic(out / "tradeoff.json", json.dumps(doc, indent=2, allow_nan=False))
    plot_pareto(doc, out / "tradeoff.png")


def plot_pareto(doc: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(10, 8))
    for ax, (_, short) in zip(axes.ravel(), QUANTITIES):
        for model in doc["models"]:
            pts = [(r["wall_time_s"], r[f"err_{short}"]) for r in doc["rows"]
                   if r["model"] == model and r[f"err_{short}"]]
            if pts:
                ax.loglog(*zip(*pts), "o-", label=model)
        refs = ", ".join(f"{g}: {ref[short]['model']}" for g, ref in doc["references"].items())
        ax.set(xlabel="wall time (s)", ylabel=f"relative error of {short}",
               title=f"{short}  (reference {refs})")
        ax.grid(True, which="both", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
        else:  # every error is zero (e.g. an area fixed by the geometry): nothing to plot
            ax.text(0.5, 0.5, "all errors zero", ha="center", transform=ax.transAxes)
    fig.suptitle(f"speed against accuracy, scene {doc['scene'].get('name', '?')}")
    save_figure(fig, path, 110)


def pareto_table(doc: dict) -> str:
    lines = [f"{'model':<9} {'level':>5} {'time s':>8} {'mem MB':>7} "
             + " ".join(f"{'err ' + s:>10}" for _, s in QUANTITIES)]
    for r in doc["rows"]:
        errs = " ".join(f"{r[f'err_{s}']:>10.2e}" if r[f"err_{s}"] is not None
                        else f"{'-':>10}" for _, s in QUANTITIES)
        flag = "" if r["converged"] else "  NOT CONVERGED"
        lines.append(f"{r['model']:<9} {r['level']:>5} {r['wall_time_s']:>8.3g} "
                     f"{r['peak_memory_MB']:>7.0f} {errs}{flag}")
    for group, refs in doc["references"].items():
        lines += _reference_lines(group, refs)
    for m, why in doc["skipped"].items():
        lines.append(f"{m}: {why}")
    return "\n".join(lines)


def _reference_lines(group: str, references: dict) -> list:
    lines = [f"references ({group}): " + "; ".join(
        f"{s} = {ref['value']:.6g} ({ref['model']}, {ref['status']}"
        + (f", order {ref['order']:.2f}" if ref["order"] else "") + ")"
        for s, ref in references.items())]
    for s, ref in references.items():
        for m, est in ref.get("per_model", {}).items():
            if est["f_exact"] is not None and est["order"] is not None:
                lines.append(f"  {s} extrapolated by {m}: {est['f_exact']:.6g} +- "
                             f"{est['band']:.2g} (order {est['order']:.2f})")
            elif est["f_exact"] is not None:
                lines.append(f"  {s} by {m}: {est['f_exact']:.6g} ({est['status']})")
            else:
                lines.append(f"  {s} extrapolated by {m}: none ({est['status']})")
    return lines
