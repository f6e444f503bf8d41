"""What each model's accuracy costs in time and memory.

For every model whose declaration has a ladder (:mod:`validation.registry`), the study solves
the scene on each of the ladder's ``rungs``, one case at a time on the engine (timings are not
shared with another case running beside them),
and records the wall time (median of ``repeats`` runs inside the case, stored with it), the
peak memory (the resident set's high-water mark during the first run, above where it
started) and the four compared quantities F_T, sigma_0, a and A.  Finished rungs are cached:
an interrupted study resumes.  The reference of each quantity cross-checks the models'
Richardson extrapolations from their three finest rungs (observed order, Celik et al. 2008;
:func:`reference_values`): pre-asymptotic estimates are not preferred, and when the others
disagree beyond their bands the reference band covers the disagreement.  The error of every
rung is |f - f_ref| / |f_ref|.

Outputs: ``tradeoff.csv`` (one row per model and rung), ``tradeoff.json`` (rows,
references with their orders and bands, scene and versions) and ``tradeoff.png`` (log-log
error against wall time, one panel per quantity, one line per model, points labelled by their
refinement, the Pareto front marked: :func:`validation.output.plots.plot_tradeoff`).

References
----------
.. [1] I. B. Celik et al., J. Fluids Eng. 130 (2008) 078001 (Richardson extrapolation, GCI).
"""

from __future__ import annotations

import csv
import io
import json
import math
import tempfile
from pathlib import Path

from pillar_xval.outcome import package_version, write_atomic
from pillar_xval.scenes import InputError

from ..engine import Case, Engine
from ..registry import QUANTITIES
from ..registry import ladders as all_ladders
from ._ladder import reference_values

# What a difference must exceed to be a trade, not noise.  A relative error below ROUND_OFF is
# floating-point round-off (the closed forms, a model that is exact on the scene): such errors
# are reported "at round-off" and are all equal on a Pareto front.  Two wall times are a tie
# when they differ by less than the larger one's noise: the spread of its repeats, and at least
# TIME_NOISE_REL of it and TIME_NOISE_S (timer and scheduling jitter of a run of milliseconds;
# a fast scene once showed P = 9 "faster" than P = 5 by 2 ms).
ROUND_OFF = 1e-12
TIME_NOISE_REL = 0.1
TIME_NOISE_S = 5e-3


def time_noise(timing: dict) -> float:
    """The noise of a rung's median wall time (s): the spread of its timed repeats, at least
    :data:`TIME_NOISE_REL` of the median and :data:`TIME_NOISE_S`."""
    times = [float(t) for t in timing.get("wall_times_s") or [timing["wall_time_s"]]]
    spread = max(times) - min(times) if len(times) > 1 else 0.0
    return max(spread, TIME_NOISE_REL * float(timing["wall_time_s"]), TIME_NOISE_S)


def physics_group(model: str, scene, options: dict | None = None) -> str:
    """Models that solve the same equations share a reference (a model's physics with the
    case's ``options``: a BEM with ``pillars = elastic`` solves the elastic pillar's); a
    model with other physics (the elastic pillar of the FEM against the Hooke pillar of the
    BEM) is measured against its own, so that its errors are discretisation errors, not the
    modelling difference (which ``pillar-xval compare`` reports).  On a flat scene every model
    solves the Hertz problem."""
    from ..registry import MODELS

    if scene.is_flat:
        return "half-space"
    return (MODELS[model].physics_of(options) if model in MODELS else "") or model


def rungs_for(ladder, coarsest=None, levels: int | None = None) -> list:
    """The rungs a model climbs, coarse to fine: the ladder's ``rungs``, or, from a given
    ``coarsest`` value, that value and the ladder's finer rungs (continued geometrically by
    the ladder's factor to at least three, for a Richardson estimate); the first ``levels``
    of them when given (continued the same way if the ladder has fewer)."""
    rungs = list(ladder.rungs)
    want = levels
    if coarsest is not None:
        h0 = ladder.size(coarsest)
        rungs = [coarsest] + [r for r in rungs if ladder.size(r) < h0 * (1.0 - 1e-12)]
        want = max(3, len(rungs)) if levels is None else levels
    while want is not None and len(rungs) < want:
        rungs.append(ladder.value(1, rungs[-1]))
    return rungs[:want] if want is not None else rungs


def check_options(models, ladders=None, *, coarsest: dict | None = None,
                  levels: int | None = None, repeats: int = 3, single_above: float = 20.0,
                  max_time: float = 600.0) -> dict:
    """Every model's rungs ({model: [values]}); InputError (one line, naming the option)
    for anything a study could only refuse after solving."""
    from ..registry import MODELS, check_option, flag

    ladders = ladders or all_ladders()
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise InputError(f"--repeats {repeats!r}: allowed range is >= 1")
    if not (isinstance(max_time, (int, float)) and max_time > 0 and max_time < math.inf):
        raise InputError(f"--max-time {max_time!r}: allowed range is (0, inf) seconds")
    if not (isinstance(single_above, (int, float)) and 0 <= single_above <= math.inf):
        raise InputError(f"--single-above {single_above!r}: allowed range is [0, inf] seconds")
    if levels is not None and not 1 <= levels <= 12:
        raise InputError(f"--levels {levels!r}: allowed range is [1, 12]")
    unknown = [m for m in models if m not in ladders]
    if unknown or not models:
        raise InputError(f"--models {','.join(models)}: no refinement ladder for "
                         f"{', '.join(unknown) or 'an empty list'}; known: "
                         f"{', '.join(sorted(ladders))}")
    plan = {}
    for name in models:
        ladder = ladders[name]
        start = (coarsest or {}).get(ladder.option)
        plan[name] = rungs_for(ladder, start, levels)
        spec = MODELS[name].options.get(ladder.option) if name in MODELS else None
        for k, value in enumerate(plan[name]):
            try:
                check_option(ladder.option, value, spec=spec)
            except InputError as exc:
                given = "" if start is None else f"{flag(ladder.option)} {start:g}, "
                raise InputError(f"{name}: {given}rung {k + 1} would be {ladder.option} = "
                                 f"{value:g}: {str(exc).split(': ', 1)[-1]}") from None
    return plan


def tradeoff(scene, models, cache_dir: Path | None = None, *, engine: Engine | None = None,
             repeats: int = 3, single_above: float = 20.0, max_time: float = 600.0,
             ladders=None, coarsest: dict | None = None, levels: int | None = None,
             options: dict | None = None) -> dict:
    """Solve every rung of every model and attach errors against the Richardson reference.

    ``options`` (``{"pillars": "elastic"}``, say) go to every model that takes them, on every
    rung; they may change a model's physics and so its reference group
    (:func:`physics_group`).

    Rungs (:func:`rungs_for`: the ladder's, or ``levels`` from ``coarsest[option]``) run one
    by one on ``engine`` (default: serial, in this process), cached in ``cache_dir`` when
    given.  A model that refuses the scene (an InputError, e.g. the FEM on a scene with
    several pillars in contact) is skipped with its reason; a model stops climbing after a
    rung slower than ``max_time`` seconds.
    """
    from ..registry import MODELS

    from ..registry import check_option

    ladders = ladders or all_ladders()
    plan = check_options(models, ladders, coarsest=coarsest, levels=levels, repeats=repeats,
                         single_above=single_above, max_time=max_time)
    for key, value in (options or {}).items():
        if value is not None:
            check_option(key, value)
    own = engine is None
    engine = engine or Engine("serial", label="tradeoff")
    scratch = None
    if cache_dir is None:
        scratch = tempfile.TemporaryDirectory(prefix="pillar-xval-tradeoff-")
        cache_dir = Path(scratch.name)
    rows, skipped = [], {}
    try:
        for name in models:
            ladder = ladders[name]
            try:
                MODELS[name].function  # noqa: B018 - imports the solver's module
            except ImportError as exc:
                skipped[name] = f"not available ({exc})"
                continue
            rungs = plan[name]
            extra = {k: v for k, v in (options or {}).items()
                     if v is not None and (name not in MODELS or k in MODELS[name].options)}
            for k, level in enumerate(rungs):
                case = Case(name, scene, {**ladder.options_at(level), **extra}, repeats=repeats,
                            single_above=single_above, tag=f"{name} {k + 1}/{len(rungs)}")
                outcome = engine.run_one(case, cache_dir, label="tradeoff")
                if isinstance(outcome.error, ValueError):  # the model refuses this scene
                    skipped[name] = f"refused {ladder.option}={level}: {outcome.error}"
                    break
                result, timing = outcome.unwrap(), outcome.timing
                row = {"model": name, "label": result.label, "option": ladder.option,
                       "level": level,
                       "h": ladder.size(level), "wall_time_s": timing["wall_time_s"],
                       "time_noise_s": time_noise(timing),
                       "peak_memory_MB": timing["peak_memory_MB"],
                       "iterations": result.iterations, "converged": bool(result.converged),
                       "message": str(result.diagnostics.get("message", "")),
                       "cached": outcome.cached,
                       "physics": physics_group(name, scene, case.options)}
                row.update(extra)
                for q in QUANTITIES:
                    row[q.key] = float(getattr(result, q.attr))
                rows.append(row)
                if timing["wall_time_s"] > max_time and k + 1 < len(rungs):
                    skipped[name] = (f"stopped after {ladder.option}={level} "
                                     f"({timing['wall_time_s']:.0f} s > --max-time)")
                    break
    finally:
        if own:
            engine.close()
        if scratch is not None:
            scratch.cleanup()
    references = {group: reference_values([r for r in rows if r["physics"] == group])
                  for group in sorted({r["physics"] for r in rows})}
    for row in rows:
        for q in QUANTITIES:
            ref = references[row["physics"]][q.key]["value"]
            row[f"err_{q.key}"] = abs(row[q.key] - ref) / abs(ref) if ref else None
    return {"scene": scene.to_dict(), "models": list(models), "rows": rows,
            "references": references, "skipped": skipped, "repeats": repeats,
            "ladders": {m: {"option": ladders[m].option, "levels": plan[m]} for m in models},
            "options": dict(options or {}), "round_off": ROUND_OFF,
            "version": package_version()}


OUTPUTS = ("tradeoff.csv", "tradeoff.png", "tradeoff.json")
CSV_COLUMNS = ("model", "physics", "option", "level", "h", "wall_time_s", "time_noise_s",
               "peak_memory_MB", "iterations",
               "converged", "F_T", "sigma0", "a", "A", "err_F_T", "err_sigma0", "err_a",
               "err_A")


def write_outputs(doc: dict, out: Path) -> None:
    """:data:`OUTPUTS` in ``out``, tradeoff.json last (its presence means a whole report)."""
    out.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, extrasaction="ignore")
    writer.writeheader()
    for row in doc["rows"]:
        writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in CSV_COLUMNS})
    write_atomic(out / "tradeoff.csv", buf.getvalue())
    from ..output.plots import plot_tradeoff

    plot_tradeoff(doc, out / "tradeoff.png")
    write_atomic(out / "tradeoff.json", json.dumps(doc, indent=2, allow_nan=False))


def _error_text(err) -> str:
    if err is None:
        return f"{'-':>10}"
    return f"{'round-off':>10}" if err < ROUND_OFF else f"{err:>10.2e}"


def pareto_table(doc: dict) -> str:
    """The rungs' times and errors (each model named with its pillar model), then each
    physics' references and what they came from."""
    width = max([9] + [len(r.get("label", r["model"])) for r in doc["rows"]])
    lines = [f"{'model':<{width}} {'level':>5} {'time s':>8} {'+-s':>7} {'mem MB':>7} "
             + " ".join(f"{'err ' + q.key:>10}" for q in QUANTITIES)]
    for r in doc["rows"]:
        errs = " ".join(_error_text(r[f"err_{s}"]) for s in (q.key for q in QUANTITIES))
        flag = "" if r["converged"] else "  NOT CONVERGED"
        noise = r.get("time_noise_s")
        lines.append(f"{r.get('label', r['model']):<{width}} {r['level']:>5} "
                     f"{r['wall_time_s']:>8.3g} "
                     f"{'-' if noise is None else format(noise, '.2g'):>7} "
                     f"{r['peak_memory_MB']:>7.0f} {errs}{flag}")
    lines.append(f"time: median of the repeats; +-: its noise (the repeats' spread, at least "
                 f"{TIME_NOISE_REL:.0%} and {TIME_NOISE_S * 1e3:g} ms): times closer than that "
                 f"are ties, not a trade; 'round-off': a relative error below {ROUND_OFF:g}")
    for group, refs in doc["references"].items():
        lines += _reference_lines(group, refs)
    for m, why in doc["skipped"].items():
        lines.append(f"{m}: {why}")
    return "\n".join(lines)


def _reference_lines(group: str, references: dict) -> list:
    """The references of one physics, each with the estimate it came from and why, then
    every model's own extrapolation marked as the reference or as a cross-check (with the
    reason it is not the reference): two extrapolated values with two orders are otherwise
    two answers to one question."""
    lines = [f"references ({group}): the value each error of this physics is measured against"]
    for s, ref in references.items():
        lines.append(f"  {s} = {ref['value']:.6g} from {ref['model']} ("
                     + (ref.get("basis") or ref["status"])
                     + (f", order {ref['order']:.2f}" if ref["order"] else "") + ")")
        used = set(str(ref.get("model") or "").split("+")) if ref.get("basis") else set()
        expected_tier = "expected order" in (ref.get("basis") or "")
        for m, est in ref.get("per_model", {}).items():
            own = est["assumed"] if expected_tier and m in used and est.get("assumed") else est
            if m in used:
                role = "the reference" if len(used) == 1 else "part of the reference"
            elif est.get("pre_asymptotic"):
                role = ("a cross-check, not used: pre-asymptotic ("
                        + "; ".join(est["pre_asymptotic"]) + ")")
            elif est["f_exact"] is None or est.get("order") is None:
                role = f"a cross-check, not used: {est['status']}"
            else:
                role = "a cross-check, not used: a wider band"
            if own["f_exact"] is None:
                lines.append(f"    {s} extrapolated by {m}: none ({est['status']})")
                continue
            how = ("at its expected order " if own is not est else "") + \
                (f"order {own['order']:.2f}" if own.get("order") is not None
                 else est["status"])
            band = f" +- {own['band']:.2g}" if own.get("band") is not None else ""
            lines.append(f"    {s} extrapolated by {m}: {own['f_exact']:.6g}{band} ({how}): "
                         f"{role}")
        lines += [f"    note: {flag}" for flag in ref.get("flags", [])]
    return lines
