"""Cost of the elastic-pillar BEM against fem-3d at equal accuracy:
``python -m validation.bench.elastic_fem3d --out DIR [--quick]`` (``make bench-elastic``).

Scenes: Phi = 0.2 (``paper-fig3-sparse`` with ``pillars.surface_fraction=0.2``) and Phi = 0.82
(``paper-fig3-dense``), Table 1 materials (E_s = E_p = E_l = 1.6 MPa, every nu = 0.5; stated
as overrides, equal to the presets' values), zeta = 0.3 um.  Models, each through
``validation.registry.run_model``:

- fem-3d at mesh_size 2.83, 2 and 1.41, one run each; a level whose memory estimate
  (``fem_reference.solid3d.driver.estimate_memory``) exceeds ``MEMORY_BUDGET_GIB`` is skipped
  and says so;
- the FFT BEM (``bem-fft``) at 8, 16, 32, 64 cells per diameter and the dense BEM (``bem``) at
  11 and 21 elements per diameter, each with ``pillars="hooke"`` and ``pillars="elastic"``:
  one warm-up run, then the median of three.  The elastic pillar's compliance comes from the
  disk cache (DIR/cache) in every run, warm-up included; each solve reloads it (a few ms) and
  rebuilds its excess-compliance block, as a single solve would.

Each case runs in a fresh interpreter; its peak memory is that process's
``getrusage(RUSAGE_SELF).ru_maxrss`` (the interpreter and its imports included: ~0.1-0.2 GiB
of every figure is that floor).  Each finished case is kept as JSON under DIR/cases, so an
interrupted run resumes where it stopped.

The reference per scene and quantity is fem-3d's Richardson estimate from its three levels
(``validation.analysis.verification.study``; ``gci["f_exact"]`` when its status is ``ok``,
else the finest level, named as such), with its GCI band.  The compliance build of each
pillar kind is timed uncached (``PILLAR_XVAL_CACHE`` pointed at a fresh DIR/compliance-build).
The claims per scene: (a) the cheapest elastic BEM level whose sigma0 is within 3 % of the
reference; (b) the cheapest fem-3d level within 3 % of the same reference, and the speed
ratio fem-3d time / elastic BEM time (cached compliance, and with the build added): target
>= 50x; the elastic/Hooke BEM time ratio at each resolution (target <= 3x); the compliance
build against 60 s.  Prints the table and writes ``elastic_fem3d.md`` and
``elastic_fem3d.json`` (atomically).  ``--quick``: Phi = 0.2 only, fem-3d at 4, 2.83, 2, the
FFT BEM at 8 and 16, the dense BEM at 11.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from validation.bench.elastic_pillar import _timed
from validation.output.formatting import markdown_table, percent

TABLE1 = ["lens.E_Pa=1.6e6", "pillars.E_Pa=1.6e6", "substrate.E_Pa=1.6e6", "lens.nu=0.5",
          "pillars.nu=0.5", "substrate.nu=0.5", "load.indentation_um=0.3"]
SCENES = {
    "0.2": ("paper-fig3-sparse", ["pillars.surface_fraction=0.2", *TABLE1]),
    "0.82": ("paper-fig3-dense", ["pillars.surface_fraction=0.82", *TABLE1]),
}
# Each model's refinement option (the resolution column).
OPTION = {"fem-3d": "mesh_size", "bem-fft": "cells_per_diameter", "bem": "elements_per_diameter"}
FULL = {"scenes": ("0.2", "0.82"), "fem-3d": (2.83, 2.0, 1.41), "bem-fft": (8, 16, 32, 64),
        "bem": (11, 21)}
QUICK = {"scenes": ("0.2",), "fem-3d": (4.0, 2.83, 2.0), "bem-fft": (8, 16), "bem": (11,)}
PILLARS = ("hooke", "elastic")
REPEATS = 3
MEMORY_BUDGET_GIB = 10.0
SIGMA0_RTOL = 0.03
SPEEDUP_TARGET = 50.0
ELASTIC_OVER_HOOKE_TARGET = 3.0
COMPLIANCE_TARGET_S = 60.0
GIB = 2.0 ** 30
MEMORY_NOTE = ("peak RSS of the case's own fresh interpreter (getrusage ru_maxrss, the "
               "interpreter and its imports included)")
TIMING_NOTE = ("BEM: median of 3 solves after one warm-up, compliance from the disk cache "
               "(reloaded and its block rebuilt per solve); fem-3d: one run, solver imported "
               "before the clock starts")


def scene_of(phi: str):
    from pillar_xval.scenes import load_scene

    preset, overrides = SCENES[phi]
    return load_scene(preset, list(overrides))


# --- the cases ------------------------------------------------------------------------------

def plan_cases(quick: bool = False, scenes=None) -> list[dict]:
    """The cases in run order: the compliance build per pillar kind, then per scene the BEMs
    (Hooke and elastic side by side per resolution) and fem-3d coarse to fine; ``scenes``
    (a subset of SCENES' keys, in that order) replaces the default scenes."""
    levels = dict(QUICK if quick else FULL)
    if scenes is not None:
        levels["scenes"] = tuple(scenes)
    cases, kinds = [], set()
    for phi in levels["scenes"]:  # one build per pillar kind (both scenes share theirs)
        scene = scene_of(phi)
        p, s = scene.pillars, scene.substrate
        kind = (p.height_m / p.diameter_m, p.material.E_Pa / s.E_Pa, p.material.nu, s.nu)
        if kind not in kinds:
            kinds.add(kind)
            cases.append({"case": "compliance", "phi": phi})
    for phi in levels["scenes"]:
        for model in ("bem-fft", "bem"):
            for res in levels[model]:
                for pil in PILLARS:
                    cases.append({"case": "bem", "phi": phi, "model": model, "pillars": pil,
                                  "resolution": res})
        for ms in levels["fem-3d"]:
            cases.append({"case": "fem", "phi": phi, "model": "fem-3d", "pillars": "elastic",
                          "resolution": ms})
    return cases


def case_id(spec: dict) -> str:
    parts = [spec["case"], f"phi{spec['phi']}"]
    if spec["case"] != "compliance":
        parts += [spec["model"], spec["pillars"], f"{spec['resolution']:g}"]
    return re.sub(r"[^A-Za-z0-9_.-]", "_", "-".join(parts))


def _peak_rss_gib() -> float:
    ru = max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
             resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    return ru * 1024.0 / GIB  # Linux: KiB


def _result_fields(res) -> dict:
    d = res.diagnostics
    unknowns = (res.discretisation.get("dofs") or d.get("unknowns") or d.get("candidate_cells"))
    return {"F_T_N": res.total_force_N, "sigma0_Pa": res.centre_pressure_Pa,
            "converged": bool(res.converged), "iterations": int(res.iterations),
            "pillars_in_contact": res.pillars_in_contact,
            "unknowns": None if unknowns is None else int(unknowns),
            "message": d.get("message", "")}


def execute_case(spec: dict) -> dict:
    """Run one case in this process (a fresh interpreter: ``--case``)."""
    from validation.registry import run_model

    load = list(os.getloadavg())
    scene = scene_of(spec["phi"])
    out = {"spec": spec, "load_average_start": load}
    if spec["case"] == "compliance":
        from bem_solver._elastic_pillar import scene_compliance
        from dataclasses import asdict

        from fem_reference import PillarKind  # (imports outside the clock)

        modal, t = _timed(scene_compliance, scene)
        if modal.diagnostics.get("cached"):
            raise RuntimeError("the compliance build came from a cache: not a build time")
        out.update({"time_s": t, "kind": asdict(PillarKind.of_scene(scene)),
                    "modes": modal.modes, "top_points": int(len(modal.r_top)),
                    "phases_s": modal.diagnostics.get("time_s")})
    elif spec["case"] == "fem":
        import fem_reference.solid3d  # noqa: F401  (imports outside the clock)

        res, t = _timed(run_model, "fem-3d", scene, mesh_size=spec["resolution"])
        out.update(_result_fields(res), time_s=t, times_s=[t],
                   fem_peak_rss_GiB=res.diagnostics.get("peak_rss_GiB"),
                   phases_s=res.diagnostics.get("time_s"))
    else:
        opts = {OPTION[spec["model"]]: spec["resolution"], "pillars": spec["pillars"]}
        _, warm = _timed(run_model, spec["model"], scene, **opts)
        times, res = [], None
        for _ in range(REPEATS):
            res, t = _timed(run_model, spec["model"], scene, **opts)
            times.append(t)
        out.update(_result_fields(res), time_s=statistics.median(times), times_s=times,
                   warmup_s=warm)
    out["peak_rss_GiB"] = _peak_rss_gib()
    out["load_average_end"] = list(os.getloadavg())
    return out


def skip_reason(spec: dict) -> str | None:
    """Why a case is not run: its memory estimate exceeds the budget."""
    if spec["case"] == "compliance":
        return None
    scene = scene_of(spec["phi"])
    if spec["model"] == "fem-3d":
        from fem_reference.solid3d.driver import estimate_memory
        need = estimate_memory(scene, spec["resolution"])["bytes"]
    elif spec["model"] == "bem":
        from bem_solver import estimate_memory
        need = estimate_memory(scene, spec["resolution"])["bytes"]
    else:
        return None
    if need > MEMORY_BUDGET_GIB * GIB:
        return (f"memory estimate {need / GIB:.1f} GiB exceeds the {MEMORY_BUDGET_GIB:g} GiB "
                "budget")
    return None


def run_case(spec: dict, out: Path) -> dict:
    """The case's JSON from DIR/cases when it finished before, else run it in a fresh
    interpreter and keep it there.  A failed case is reported and not kept (a resumed run
    retries it)."""
    from pillar_xval.outcome import write_atomic

    path = out / "cases" / f"{case_id(spec)}.json"
    if path.exists():
        try:
            row = json.loads(path.read_text())
            row["cached"] = True
            return row
        except (OSError, ValueError):
            pass
    reason = skip_reason(spec)
    if reason is not None:
        return {"spec": spec, "skipped": reason}
    env = dict(os.environ)
    if spec["case"] == "compliance":
        build = out / "compliance-build"
        shutil.rmtree(build, ignore_errors=True)
        env["PILLAR_XVAL_CACHE"] = str(build)
    else:
        env["PILLAR_XVAL_CACHE"] = str(out / "cache")
    tmp = out / "cases" / f".{case_id(spec)}.running.json"
    tmp.parent.mkdir(parents=True, exist_ok=True)
    proc = subprocess.run([sys.executable, "-m", "validation.bench.elastic_fem3d",
                           "--case", json.dumps(spec), "--case-out", str(tmp)],
                          env=env, capture_output=True, text=True)
    if proc.returncode != 0 or not tmp.exists():
        return {"spec": spec, "error": (proc.stderr or proc.stdout).strip()[-2000:]}
    row = json.loads(tmp.read_text())
    tmp.unlink()
    if spec["case"] == "compliance":  # the cached runs start from this build
        shutil.copytree(out / "compliance-build", out / "cache", dirs_exist_ok=True)
    write_atomic(path, json.dumps(row, indent=1))
    row["cached"] = False
    return row


# --- analysis -------------------------------------------------------------------------------

def _ok(row: dict) -> bool:
    return "error" not in row and "skipped" not in row and row.get("converged", False)


def reference(fem_rows: list, key: str) -> dict:
    """fem-3d's estimate of ``key`` from its converged levels: the Richardson value when the
    three-grid study's status is ok, else the finest level (``basis`` says which)."""
    from validation.analysis.verification import study

    ok = sorted((r for r in fem_rows if _ok(r)), key=lambda r: r["spec"]["resolution"])
    if not ok:
        return {"value": None, "basis": "no converged fem-3d level", "band": None,
                "status": None, "levels": []}
    h = [r["spec"]["resolution"] for r in ok]
    f = [r[key] for r in ok]
    if len(ok) == 1:
        return {"value": f[0], "basis": f"finest level (mesh_size {h[0]:g}; one level)",
                "band": None, "status": "one-level", "levels": h}
    st = study(h, f)
    g = st["gci"]
    if g["status"] == "ok":
        return {"value": g["f_exact"], "basis": "Richardson", "band": g["gci_fine"],
                "status": "ok", "order": g["order"], "levels": h, "study": st}
    return {"value": f[0], "basis": f"finest level (mesh_size {h[0]:g}; {g['status']})",
            "band": g["fallback_uncertainty"] / abs(f[0]) if f[0] else None,
            "status": g["status"], "levels": h, "study": st}


def analyse(rows: list, rtol: float = SIGMA0_RTOL) -> dict:
    """References, relative errors (in place on ``rows``), time ratios and claims."""
    builds = [r for r in rows if r["spec"]["case"] == "compliance" and "time_s" in r]
    build_s = max((b["time_s"] for b in builds), default=None)
    solves = [r for r in rows if r["spec"]["case"] != "compliance"]
    phis = list(dict.fromkeys(r["spec"]["phi"] for r in solves))
    refs, claims, ratios = {}, {}, []
    for phi in phis:
        mine = [r for r in solves if r["spec"]["phi"] == phi]
        fem = [r for r in mine if r["spec"]["model"] == "fem-3d"]
        refs[phi] = {"F_T": reference(fem, "F_T_N"), "sigma0": reference(fem, "sigma0_Pa")}
        for r in mine:
            if "F_T_N" in r:
                for q, key in (("F_T", "F_T_N"), ("sigma0", "sigma0_Pa")):
                    ref = refs[phi][q]["value"]
                    r[f"err_{q}"] = None if not ref else r[key] / ref - 1.0
        for model in ("bem-fft", "bem"):
            by_res = {}
            for r in mine:
                if r["spec"]["model"] == model and _ok(r):
                    by_res.setdefault(r["spec"]["resolution"], {})[r["spec"]["pillars"]] = r
            for res, pair in sorted(by_res.items()):
                if set(pair) >= set(PILLARS):
                    ratios.append({"phi": phi, "model": model, "resolution": res,
                                   "ratio": pair["elastic"]["time_s"] / pair["hooke"]["time_s"]})
        claims[phi] = _claims(phi, mine, refs[phi], build_s, rtol,
                              [x for x in ratios if x["phi"] == phi])
    return {"references": refs, "claims": claims, "ratios": ratios,
            "compliance": [{"kind": b.get("kind"), "time_s": b["time_s"],
                            "phases_s": b.get("phases_s"),
                            "met": b["time_s"] <= COMPLIANCE_TARGET_S} for b in builds],
            "compliance_target_s": COMPLIANCE_TARGET_S}


def _label(r: dict) -> str:
    s = r["spec"]
    return f"{s['model']} {s['pillars']} {OPTION[s['model']]}={s['resolution']:g}"


def _within(r: dict, rtol: float) -> bool:
    return _ok(r) and r.get("err_sigma0") is not None and abs(r["err_sigma0"]) <= rtol


def _claims(phi, rows, refs, build_s, rtol, ratios) -> dict:
    elastic = [r for r in rows if r["spec"]["model"] != "fem-3d"
               and r["spec"]["pillars"] == "elastic"]
    fem = [r for r in rows if r["spec"]["model"] == "fem-3d"]
    good = sorted((r for r in elastic if _within(r, rtol)), key=lambda r: r["time_s"])
    out = {"phi": phi, "rtol": rtol, "reference_basis": refs["sigma0"]["basis"],
           "bem_accurate_levels": [_label(r) for r in good]}
    bem = good[0] if good else None
    out["bem"] = None if bem is None else {"label": _label(bem), "time_s": bem["time_s"],
                                           "err_sigma0": bem["err_sigma0"],
                                           "err_F_T": bem.get("err_F_T")}
    fem_good = sorted((r for r in fem if _within(r, rtol)), key=lambda r: r["time_s"])
    fem_done = [r for r in fem if _ok(r)]
    if fem_good:
        f = fem_good[0]
        out["fem"] = {"label": _label(f), "time_s": f["time_s"], "err_sigma0": f["err_sigma0"],
                      "lower_bound": False,
                      "is_reference": refs["sigma0"]["basis"] != "Richardson"
                      and f["spec"]["resolution"] == min(refs["sigma0"]["levels"])}
    elif fem_done:  # none within rtol: the finest level's time bounds fem-3d's from below
        f = min(fem_done, key=lambda r: r["spec"]["resolution"])
        out["fem"] = {"label": _label(f), "time_s": f["time_s"], "err_sigma0": f["err_sigma0"],
                      "lower_bound": True, "is_reference": False}
    else:
        out["fem"] = None
    if bem is not None and out["fem"] is not None:
        out["speedup"] = out["fem"]["time_s"] / bem["time_s"]
        out["speedup_with_build"] = (None if build_s is None
                                     else out["fem"]["time_s"] / (bem["time_s"] + build_s))
        out["speedup_met"] = out["speedup"] >= SPEEDUP_TARGET
        out["speedup_with_build_met"] = (None if build_s is None
                                         else out["speedup_with_build"] >= SPEEDUP_TARGET)
    else:
        out.update(speedup=None, speedup_with_build=None, speedup_met=False,
                   speedup_with_build_met=False)
    out["sigma0_met"] = bem is not None
    at = None if bem is None else next(
        (x for x in ratios if x["model"] == bem["spec"]["model"]
         and x["resolution"] == bem["spec"]["resolution"]), None)
    out["elastic_over_hooke_at_bem"] = None if at is None else at["ratio"]
    out["elastic_over_hooke_max"] = max((x["ratio"] for x in ratios), default=None)
    out["elastic_over_hooke_met"] = [x["ratio"] <= ELASTIC_OVER_HOOKE_TARGET for x in ratios]
    return out


# --- output ---------------------------------------------------------------------------------

COLUMNS = ("Phi", "model", "pillars", "res", "unknowns", "time s", "RSS GiB", "F_T uN",
           "dF_T", "sigma0 kPa", "dsigma0", "note")


def _pct(x) -> str:
    return percent(x, "+.2f", missing="")


def table_rows(rows: list) -> list[list[str]]:
    out = []
    for r in rows:
        s = r["spec"]
        if s["case"] == "compliance":
            continue
        cells = [s["phi"], s["model"], s["pillars"], f"{s['resolution']:g}"]
        if "skipped" in r or "error" in r:
            note = ("skipped: " + r["skipped"]) if "skipped" in r else \
                ("failed: " + r["error"].splitlines()[-1][:80] if r["error"] else "failed")
            out.append(cells + [""] * 7 + [note])
            continue
        note = "" if r["converged"] else "NOT CONVERGED"
        if r.get("cached"):
            note = (note + " (kept from an earlier run)").strip()
        out.append(cells + [
            "" if r.get("unknowns") is None else str(r["unknowns"]), f"{r['time_s']:.3g}",
            f"{r['peak_rss_GiB']:.2f}", f"{r['F_T_N'] * 1e6:.5g}", _pct(r.get("err_F_T")),
            f"{r['sigma0_Pa'] * 1e-3:.5g}", _pct(r.get("err_sigma0")), note])
    return out


def format_table(rows: list) -> str:
    body = table_rows(rows)
    widths = [max(len(c), *(len(b[i]) for b in body)) if body else len(c)
              for i, c in enumerate(COLUMNS)]
    line = lambda cells: "  ".join(c.rjust(w) for c, w in zip(cells, widths)).rstrip()  # noqa
    head = line(COLUMNS)
    return "\n".join([head, "-" * len(head)] + [line(b) for b in body])


def _ref_line(phi: str, q: str, ref: dict) -> str:
    if ref["value"] is None:
        return f"Phi = {phi} {q}: {ref['basis']}"
    unit, scale = ("uN", 1e6) if q == "F_T" else ("kPa", 1e-3)
    band = "" if ref["band"] is None else f", band {100 * ref['band']:.2f} %"
    order = f", order {ref['order']:.2f}" if ref.get("order") else ""
    kind = "GCI" if ref["basis"] == "Richardson" else "Fs = 3 spread"
    return (f"Phi = {phi} {q} reference {ref['value'] * scale:.6g} {unit}: {ref['basis']} "
            f"from mesh_size {', '.join(f'{h:g}' for h in ref['levels'])}{order}"
            + (band.replace("band", kind) if band else ""))


def claim_lines(analysis: dict) -> list[str]:
    lines = []
    for phi, c in analysis["claims"].items():
        pct = f"{100 * c['rtol']:g} %"
        if c["bem"] is None:
            lines.append(f"Phi = {phi} (a) sigma0 within {pct}: NOT MET, no elastic BEM level "
                         "reaches it")
        else:
            b = c["bem"]
            lines.append(f"Phi = {phi} (a) sigma0 within {pct}: met; cheapest elastic BEM "
                         f"{b['label']} ({b['time_s']:.3g} s, sigma0 {_pct(b['err_sigma0'])}, "
                         f"F_T {_pct(b['err_F_T'])}); within: "
                         + ", ".join(c["bem_accurate_levels"]))
        f = c["fem"]
        if f is None:
            lines.append(f"Phi = {phi} (b) no converged fem-3d level")
        else:
            what = ("no fem-3d level within " + pct + f"; its finest, {f['label']}, "
                    f"{f['time_s']:.3g} s, bounds it from below" if f["lower_bound"] else
                    f"cheapest fem-3d within {pct} of its own estimate: {f['label']} "
                    f"({f['time_s']:.3g} s, sigma0 {_pct(f['err_sigma0'])}"
                    + (", itself the reference" if f["is_reference"] else "") + ")")
            lines.append(f"Phi = {phi} (b) {what}")
        if c["speedup"] is not None:
            ge = ">= " if f["lower_bound"] else ""
            wb = ("" if c["speedup_with_build"] is None else
                  f"; with the compliance build {ge}{c['speedup_with_build']:.3g}x "
                  f"({'met' if c['speedup_with_build_met'] else 'NOT MET'})")
            lines.append(f"Phi = {phi} speed at equal accuracy: fem-3d / elastic BEM = "
                         f"{ge}{c['speedup']:.3g}x (target >= {SPEEDUP_TARGET:g}x: "
                         f"{'met' if c['speedup_met'] else 'NOT MET'}){wb}")
        else:
            lines.append(f"Phi = {phi} speed at equal accuracy: no ratio (target >= "
                         f"{SPEEDUP_TARGET:g}x: NOT MET)")
        rs = [x for x in analysis["ratios"] if x["phi"] == phi]
        if rs:
            n_met = sum(c["elastic_over_hooke_met"])
            at = c["elastic_over_hooke_at_bem"]
            lines.append(f"Phi = {phi} elastic/Hooke time: "
                         + ", ".join(f"{x['model']} {x['resolution']:g}: {x['ratio']:.2f}x"
                                     for x in rs)
                         + f"; <= {ELASTIC_OVER_HOOKE_TARGET:g}x at {n_met} of {len(rs)}"
                         + ("" if at is None else f"; at the cheapest accurate level "
                            f"{at:.2f}x"))
    for b in analysis["compliance"]:
        k = b["kind"] or {}
        kind = ", ".join(f"{name} {k[key]:g}" for key, name in (
            ("height_over_diameter", "h/d"), ("modulus_ratio", "E_p/E_s"), ("nu_pillar", "nu_p"),
            ("nu_substrate", "nu_s")) if key in k)
        lines.append(f"compliance build per pillar kind ({kind or 'kind not recorded'}; "
                     f"uncached): {b['time_s']:.1f} s "
                     f"(target <= {COMPLIANCE_TARGET_S:g} s: "
                     f"{'met' if b['met'] else 'NOT MET'})")
    return lines


def reference_lines(analysis: dict) -> list[str]:
    return [_ref_line(phi, q, refs[q]) for phi, refs in analysis["references"].items()
            for q in ("F_T", "sigma0")]


def render_markdown(doc: dict) -> str:
    body = table_rows(doc["rows"])
    out = ["# Elastic-pillar BEM against fem-3d: cost at equal accuracy", "",
           f"`{doc['command']}`: wall time {doc['wall_s']:.0f} s, load average "
           f"{_load(doc['load_average_start'])} at the start, {_load(doc['load_average_end'])}"
           f" at the end; {doc['machine']}.", "",
           *markdown_table(COLUMNS, body)]
    out += ["", "dF_T, dsigma0: relative to the reference below.  " + TIMING_NOTE
            + ".  Memory: " + MEMORY_NOTE + ".", "", "## References", ""]
    out += [f"- {x}" for x in doc["reference_lines"]]
    out += ["", "## Claims", ""] + [f"- {x}" for x in doc["claim_lines"]] + [""]
    return "\n".join(out)


def _load(triple) -> str:
    return "/".join(f"{x:.2f}" for x in triple)


def write_outputs(out: Path, doc: dict) -> tuple[Path, Path]:
    from pillar_xval.outcome import write_atomic

    md = write_atomic(out / "elastic_fem3d.md", render_markdown(doc))
    js = write_atomic(out / "elastic_fem3d.json", json.dumps(doc, indent=1, allow_nan=False))
    return md, js


def run(out: Path, quick: bool = False, runner=run_case, log=print, scenes=None) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    load0 = list(os.getloadavg())
    rows = []
    for spec in plan_cases(quick, scenes):
        row = runner(spec, out)
        rows.append(row)
        log(_progress(row), flush=True)
    analysis = analyse(rows)
    import platform
    doc = {"benchmark": "elastic-pillar BEM against fem-3d at equal accuracy",
           "command": "python -m validation.bench.elastic_fem3d --out " + str(out)
                      + (" --quick" if quick else "")
                      + (f" --scenes {','.join(scenes)}" if scenes else ""),
           "quick": quick, "machine": f"{os.cpu_count()} cores, {platform.machine()}, shared "
                                      "with other jobs (timings contended)",
           "load_average_start": load0, "load_average_end": list(os.getloadavg()),
           "wall_s": time.perf_counter() - t0, "timing": TIMING_NOTE, "memory": MEMORY_NOTE,
           "scenes": {k: {"preset": v[0], "overrides": v[1]} for k, v in SCENES.items()},
           "memory_budget_GiB": MEMORY_BUDGET_GIB, "rows": rows, **analysis}
    doc["reference_lines"] = reference_lines(analysis)
    doc["claim_lines"] = claim_lines(analysis)
    write_outputs(out, doc)
    log(format_table(rows))
    for line in doc["reference_lines"] + doc["claim_lines"]:
        log(line)
    log(f"load average {_load(load0)} at the start, {_load(doc['load_average_end'])} at the "
        f"end; wall time {doc['wall_s']:.0f} s; wrote {out / 'elastic_fem3d.md'} and .json")
    return doc


def _progress(row: dict) -> str:
    s = row["spec"]
    name = "compliance build" if s["case"] == "compliance" else _label(row)
    if "skipped" in row:
        return f"Phi {s['phi']} {name}: skipped ({row['skipped']})"
    if "error" in row:
        return f"Phi {s['phi']} {name}: FAILED {row['error'][-300:]}"
    extra = "" if s["case"] == "compliance" else \
        f", F_T {row['F_T_N']:.6g} N, sigma0 {row['sigma0_Pa']:.6g} Pa"
    return (f"Phi {s['phi']} {name}: {row['time_s']:.3g} s, {row['peak_rss_GiB']:.2f} GiB"
            f"{extra}{' (kept)' if row.get('cached') else ''}; load "
            f"{_load(os.getloadavg())}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation.bench.elastic_fem3d",
                                 description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path)
    ap.add_argument("--quick", action="store_true",
                    help="Phi = 0.2 only, coarse levels (fem-3d 4, 2.83, 2; FFT 8, 16; P 11)")
    ap.add_argument("--scenes", type=lambda t: t.split(","), default=None, metavar="PHI,...",
                    help=f"scenes to run, a subset of {','.join(SCENES)} (default: all; "
                         "with --quick: 0.2)")
    ap.add_argument("--case", help=argparse.SUPPRESS)
    ap.add_argument("--case-out", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.case:
        from pillar_xval.outcome import write_atomic

        write_atomic(args.case_out, json.dumps(execute_case(json.loads(args.case))))
        return 0
    if args.out is None:
        ap.error("--out is required")
    bad = [v for v in args.scenes or () if v not in SCENES]
    if bad:
        ap.error(f"--scenes {','.join(bad)}: allowed values are {', '.join(SCENES)}")
    run(args.out, args.quick, scenes=args.scenes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
