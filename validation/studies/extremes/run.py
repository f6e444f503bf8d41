"""``pillar-xval extremes``: every model over the corners and edges of the parameter space.

Parameters and their extremes (the nominal scene is the paper's Fig. 3a, Table 1):

=============  =====================  ==========
parameter      extremes               nominal
=============  =====================  ==========
E_p / E_l      1e-3, 1e6              1
E_s / E_l      1e-3, 1e6              1
Phi            0.002, 0.9             0.03
zeta / h       0.0025, 0.99           0.15
R              10 d (40.04 um), 1 m   2 mm
nu (all)       0, 0.3, 0.4999, 0.5    0.5
=============  =====================  ==========

R = 10 d is taken just above the scene rule R > 10 max(d, h).  Past the pillar tops (the
floor between the pillars a candidate, :data:`FLOOR_SCENES`): deep indentation (zeta = 10 h),
short pillars (h/d = 0.05 at zeta = 5 h), close packing under a large load (Phi = 0.9,
zeta = 5 h) and soft and stiff pillars (E_p/E_l = 1e-3 and 1e6 at zeta = 3 h), each on a
0.25 mm lens (10 h within its small-slope limit, 0.106 R; its grid ~1e7 FFT points at N = 16
at 10 h, the paper's 2 mm lens would need 1e8).
The scenes: the nominal one,
its edges (one parameter at an extreme), every corner of the first five parameters at
nu = 0.5, the two mismatched materials (E_p/E_l = 1e6 on E_s/E_l = 1e-3 and the reverse)
at every nu, each nu at the nominal scene, and flat scenes at the corners of E_s / E_l, R
and zeta / R.

Each model (bem P = 7, bem-fft N = 16 with at most 3000 CG iterations, fem-axisym mesh_size
2, fem-3d 4, hertz, spring: cheap resolutions, the point is robustness) runs each scene
three times: as is, with zeta 5 % deeper, and with a stiffer body (E_p x 1.5; E_s x 1.5 for
rigid pillars or a flat scene).
Each run records whether it converged, its iterations, residual and time, and the invariants:

- force balance: the pillar forces add up to F_T (relative 1e-6), F_T > 0 and finite;
- p >= 0 everywhere (relative to the largest pressure, 1e-9);
- no interpenetration: at most 1e-6 zeta (the FEMs' mortar contact: 20 % of zeta at the P2
  points next to a contact edge: models declared with ``weak_contact``, see
  :func:`interpenetration_tol`);
- F increases with zeta and with the stiffness (to :data:`RTOL_MONOTONE`).

A corner ends as ``pass`` (converged, invariants hold), ``fail`` (converged, an invariant
broken: a bug), ``not converged`` (the model said it could not resolve the scene),
``refused`` (a ScopeError or InputError up front, with its reason), ``skipped`` (fem-3d on a
lattice too wide to run three times here: :data:`FEM3D_MAX_DOFS`) or ``error`` (any other
exception: a bug).  Cases run on the engine, so an interrupted run resumes.
"""

from __future__ import annotations

import itertools
import math
import time
from pathlib import Path

import numpy as np

from pillar_xval.scenes import InputError, load_scene

from ...engine import Case, Engine, Outcome
from ...registry import MODELS

__all__ = ["corner_scenes", "model_options", "run_extremes"]

BASE = "paper-fig3-sparse"
E_LENS, D_UM, H_UM = 1.6e6, 4.0, 2.0
EXTREMES = {"Ep": (1e-3, 1e6), "Es": (1e-3, 1e6), "Phi": (0.002, 0.9),
            "zeta": (0.0025, 0.99), "R": (10.01 * D_UM * 1e-3, 1000.0)}
NOMINAL = {"Ep": 1.0, "Es": 1.0, "Phi": 0.03, "zeta": 0.15, "R": 2.0, "nu": 0.5}
NUS = (0.0, 0.3, 0.4999)
# Flat scenes: zeta / R at its shallow end (held at 1.5 nm at least) and near its limit 0.106.
FLAT_ZETA_R = (1e-6, 0.1)
# The floor's extremes: label and overrides of the nominal scene (module docstring).
FLOOR_LENS = ["lens.radius_mm=0.25"]
FLOOR_SCENES = {
    "floor: zeta=10h": FLOOR_LENS + [f"load.indentation_um={10 * H_UM!r}"],
    "floor: h/d=0.05 zeta=5h": FLOOR_LENS + ["pillars.height_um=0.2", "load.indentation_um=1.0"],
    "floor: Phi=0.9 zeta=5h": FLOOR_LENS + ["pillars.surface_fraction=0.9",
                                            f"load.indentation_um={5 * H_UM!r}"],
    "floor: Ep- zeta=3h": FLOOR_LENS + [f"pillars.E_Pa={E_LENS * 1e-3!r}",
                                        f"load.indentation_um={3 * H_UM!r}"],
    "floor: Ep+ zeta=3h": FLOOR_LENS + [f"pillars.E_Pa={E_LENS * 1e6!r}",
                                        f"load.indentation_um={3 * H_UM!r}"],
}
# fem-3d runs where its estimated unknowns at mesh_size 4 stay below this (~30 s, 2 GiB on two
# cores); wider lattices (a 1 m lens, Phi = 0.9 at a deep zeta: 100-1e6 sector pillars) are
# "skipped" with the estimate: three runs each would take hours on this machine.  Those that
# would not fit in memory at all are refused by the model itself.
FEM3D_MAX_DOFS = 1.5e5
ZETA_STEP = 1.05
STIFFER = 1.5
RTOL_FORCE_BALANCE = 1e-6
RTOL_NEGATIVE_PRESSURE = 1e-9
# Interpenetration allowed to a model with a strong contact constraint (share of zeta).
INTERPENETRATION_DEFAULT = 1e-6
# F may not fall by more than this (relative) when zeta or a modulus grows.  Where the
# stiffened body carries a negligible share of the compliance (pillars 1e6 E_l on a substrate
# 1e-3 E_l) the true increase is below 1e-9 and round-off decides the sign: fem-3d's solves at
# that 1e9 modulus contrast carry 2e-6 to 7e-6 of it (measured here: E_p x 1.5 "lowers" F by
# that much).  1e-5 is far below any increase a model resolves.
RTOL_MONOTONE = 1e-5


def model_options(quick: bool = False) -> dict[str, dict]:
    """The models that run here and the cheap options of each (their declarations'
    ``robustness``; ``robustness_quick`` in the fast subset, where one is declared)."""
    return {m.name: (m.robustness_quick if quick and m.robustness_quick is not None
                     else m.robustness)
            for m in MODELS.values() if m.robustness is not None}


def interpenetration_tol(model: str) -> float:
    """The pointwise interpenetration (share of zeta) a converged run of ``model`` may show.

    A model with weak (mortar) contact, the FEMs, holds the weighted gaps to its contact
    residual, while the pointwise gap at the P2 points beside a contact edge dips below zero
    by a share of zeta (1-3 % on resolved edges, ~9 % beside a flat punch's singular edge).
    The FEMs themselves call a run beyond ``fem_reference._driver.MAX_POINTWISE_PENETRATION``
    under-resolved (not converged); a converged run beyond it would be a bug."""
    if model in MODELS and MODELS[model].weak_contact:
        from fem_reference._driver import MAX_POINTWISE_PENETRATION

        return MAX_POINTWISE_PENETRATION
    return INTERPENETRATION_DEFAULT


def _sets(p: dict) -> list:
    """Overrides (file units) of a pillar scene with parameters ``p``."""
    nu = p["nu"]
    return [f"pillars.E_Pa={E_LENS * p['Ep']!r}", f"substrate.E_Pa={E_LENS * p['Es']!r}",
            f"pillars.surface_fraction={p['Phi']!r}",
            f"load.indentation_um={H_UM * p['zeta']!r}", f"lens.radius_mm={p['R']!r}",
            f"lens.nu={nu!r}", f"pillars.nu={nu!r}", f"substrate.nu={nu!r}"]


def _label(p: dict) -> str:
    parts = []
    for k, (lo, hi) in EXTREMES.items():
        if p[k] == lo:
            parts.append(f"{k}-")
        elif p[k] == hi:
            parts.append(f"{k}+")
    if p["nu"] != NOMINAL["nu"]:
        parts.append(f"nu={p['nu']:g}")
    return " ".join(parts) or "nominal"


def corner_scenes(quick: bool = False) -> list:
    """The scenes of the module docstring (``quick``: the nominal scene, two edges, two
    corners and a flat scene, for the fast tests)."""
    params = [dict(NOMINAL)]
    for k, values in EXTREMES.items():
        params += [dict(NOMINAL, **{k: v}) for v in values]
    params += [dict(NOMINAL, nu=nu) for nu in NUS]
    keys = list(EXTREMES)
    params += [dict(NOMINAL, **dict(zip(keys, combo)))
               for combo in itertools.product(*(EXTREMES[k] for k in keys))]
    for nu in (NOMINAL["nu"],) + NUS:  # pillars much stiffer than the substrate, and softer
        params += [dict(NOMINAL, Ep=1e6, Es=1e-3, nu=nu), dict(NOMINAL, Ep=1e-3, Es=1e6, nu=nu)]
    if quick:
        params = [params[0], dict(NOMINAL, Ep=1e-3, Es=1e6), dict(NOMINAL, zeta=0.0025),
                  dict(NOMINAL, nu=0.0)]
    out, seen = [], set()
    for p in params:
        label = _label(p)
        if label in seen:
            continue
        seen.add(label)
        out.append({"label": label, "params": p, "sets": _sets(p),
                    "scene": load_scene(BASE, _sets(p)).replace(name=label.replace(" ", "_"))})
    if not quick:
        for label, sets in FLOOR_SCENES.items():
            out.append({"label": label, "params": {"floor": True}, "sets": sets,
                        "scene": load_scene(BASE, sets).replace(
                            name=label.replace(" ", "_").replace(":", ""))})
    flats = [{"Es": es, "R": r, "zeta_r": zr} for es in (1e-3, 1e6) for r in (0.04004, 1000.0)
             for zr in FLAT_ZETA_R]
    if quick:
        flats = flats[:1]
    for f in flats:
        # zeta no shallower than the 1 nm floor of a length (scenes._checks)
        zeta_um = max(f["zeta_r"] * f["R"] * 1e3, 1.5e-3)
        sets = [f"substrate.E_Pa={E_LENS * f['Es']!r}", f"lens.radius_mm={f['R']!r}",
                f"load.indentation_um={zeta_um!r}"]
        label = f"flat Es{'-' if f['Es'] < 1 else '+'} R{'-' if f['R'] < 1 else '+'} " \
                f"zeta/R{'-' if f['zeta_r'] < 0.1 else '+'}"
        out.append({"label": label, "params": {"flat": True, **f}, "sets": sets,
                    "scene": load_scene("hertz", sets).replace(name=label.replace(" ", "_"))})
    return out


def _deeper(scene):
    """The scene 5 % deeper, or half way to the small-slope limit where that is nearer."""
    from pillar_xval.scenes._checks import small_slope_indentation

    top = small_slope_indentation(scene.lens.radius_m)
    zeta = min(scene.indentation_m * ZETA_STEP, 0.5 * (scene.indentation_m + top))
    return scene.replace(indentation_m=zeta, name=scene.name + "+zeta")


def _stiffer(scene):
    """E_p x 1.5, or E_s x 1.5 when the pillars are rigid or absent; and which."""
    from pillar_xval.scenes import Material

    if scene.pillars is not None and not scene.pillars.material.rigid:
        p = scene.pillars
        mat = Material(p.material.E_Pa * STIFFER, p.material.nu)
        return scene.replace(pillars=p.__class__(p.diameter_m, p.height_m, p.pitch_m, mat),
                             name=scene.name + "+Ep"), "E_p"
    s = scene.substrate
    return scene.replace(substrate=Material(s.E_Pa * STIFFER, s.nu),
                         name=scene.name + "+Es"), "E_s"


def skip_reason(model: str, scene, options: dict) -> str | None:
    """Why ``model`` is not run on ``scene`` for cost (fem-3d beyond :data:`FEM3D_MAX_DOFS`),
    or None.  A scene the model cannot take at all is left to the model to refuse."""
    if model != "fem-3d":
        return None
    from fem_reference.solid3d import estimate_memory

    try:
        est = estimate_memory(scene, options["mesh_size"])
    except InputError:
        return None
    if est["dofs"] <= FEM3D_MAX_DOFS:
        return None
    return (f"skipped for cost: {est['pillars']} sector pillars, ~{est['dofs']:.2g} unknowns at "
            f"mesh_size {options['mesh_size']:g} (limit {FEM3D_MAX_DOFS:.2g}; run it alone "
            "with `pillar-xval solve --model fem-3d`)")


def _cases(entry: dict, quick: bool = False) -> list:
    stiff, which = _stiffer(entry["scene"])
    entry["stiffened"] = which
    entry["skipped"] = {}
    out = []
    for model, options in model_options(quick).items():
        why = skip_reason(model, _deeper(entry["scene"]), options)
        if why:
            entry["skipped"][model] = why
            continue
        fields = MODELS[model].keeps_fields
        out += [Case(model, entry["scene"], options, fields=fields,
                     tag=f"{entry['label']}: {model}"),
                Case(model, _deeper(entry["scene"]), options,
                     tag=f"{entry['label']} +zeta: {model}"),
                Case(model, stiff, options, tag=f"{entry['label']} +{which}: {model}")]
    return out


def _run_all(engine: Engine, cases: list, folder: Path) -> list:
    """Outcomes of every case; an exception outside the engine's per-case errors (a bug in a
    model) is caught per case by running the rest one at a time."""
    try:
        return engine.run(cases, folder, label="extremes")
    except KeyboardInterrupt:
        raise
    except Exception:  # noqa: BLE001 - a crash is a finding, recorded per case below
        pass
    out = []
    for case in cases:
        try:
            out.append(engine.run_one(case, folder, label="extremes"))
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # noqa: BLE001
            out.append(Outcome(case, error=exc))
    return out


def _pressure_min_ratio(outcome) -> float | None:
    arrays = outcome.field_arrays()
    p = arrays.get("pressure_Pa", arrays.get("contact_pressure_Pa"))
    if p is None:
        p = np.asarray(outcome.result.pillar_top_profile.get("pressure_Pa", []), dtype=float)
    if p is None or not len(p):
        return None
    top = float(np.max(np.abs(p)))
    return float(p.min() / top) if top > 0 else 0.0


def _interpenetration(result) -> float | None:
    d = result.diagnostics
    zeta = result.scene["load"]["indentation_m"]
    if "max_pointwise_penetration" in d:
        return float(d["max_pointwise_penetration"])  # already over zeta
    for key in ("max_interpenetration_m", "max_gap_violation_m"):
        if key in d:
            return float(d[key]) / zeta
    return 0.0 if d.get("message") == "closed form" else None


def _status_of(outcome) -> tuple[str, str]:
    """("ok" | "refused" | "error", why): a refusal is the model's up-front InputError or
    ScopeError; anything else raised (a tool failure, a crash) is an error."""
    if outcome.ok:
        return "ok", ""
    err = outcome.error
    kind = "refused" if isinstance(err, InputError) else "error"
    return kind, f"{type(err).__name__}: {err}"


def judge(entry: dict, model: str, base, deeper, stiffer) -> dict:
    """One model on one corner: the record and its verdict."""
    rec = {"corner": entry["label"], "model": model,
           "options": dict(base.case.options), "stiffened": entry.get("stiffened")}
    status, why = _status_of(base)
    if status != "ok":
        rec.update(status=status, reason=why)
        return rec
    r = base.result
    d = r.diagnostics
    F = r.total_force_N
    checks = {}
    checks["force_positive"] = bool(math.isfinite(F) and F > 0)
    if r.pillar_forces:
        total = sum(p.force_N for p in r.pillar_forces)
        checks["force_balance"] = bool(abs(total - F) <= RTOL_FORCE_BALANCE * abs(F))
    pmin = _pressure_min_ratio(base)
    checks["pressure_nonnegative"] = None if pmin is None else bool(
        pmin >= -RTOL_NEGATIVE_PRESSURE)
    pen = _interpenetration(r)
    tol = interpenetration_tol(model)
    checks["no_interpenetration"] = None if pen is None else bool(pen <= tol)
    for key, other in (("F_increases_with_zeta", deeper), ("F_increases_with_E", stiffer)):
        if other.ok and other.result.converged and r.converged:
            checks[key] = bool(other.result.total_force_N >= F * (1.0 - RTOL_MONOTONE))
        else:
            checks[key] = None
    rec.update(converged=bool(r.converged), iterations=int(r.iterations),
               residual=d.get("contact_residual", d.get("linear_residual")),
               message=d.get("message", ""), wall_time_s=base.timing["wall_time_s"],
               F_T=F, sigma0=r.centre_pressure_Pa, pillars=r.pillars_in_contact,
               min_pressure_ratio=pmin, interpenetration_over_zeta=pen, checks=checks,
               companions={k: status_of_other(o) for k, o in (("deeper", deeper),
                                                              ("stiffer", stiffer))})
    broken = [k for k, v in checks.items() if v is False]
    if not r.converged:  # a run that says it did not converge promises no invariant
        rec.update(status="not converged", reason=d.get("message", "") + (
            f" (unconverged state breaks: {', '.join(broken)})" if broken else ""))
    elif broken:
        rec.update(status="fail", reason="broken: " + ", ".join(broken))
    else:
        rec.update(status="pass", reason="")
    return rec


def status_of_other(o) -> str:
    s, why = _status_of(o)
    if s != "ok":
        return f"{s}: {why}"
    return "converged" if o.result.converged else "not converged: " + \
        str(o.result.diagnostics.get("message", ""))


def run_extremes(out: Path, engine: Engine | None = None, *, quick: bool = False,
                 models=None) -> dict:
    """Run (or resume) every model on every corner; returns the records and the scenes."""
    t0 = time.perf_counter()
    entries = corner_scenes(quick)
    chosen = [m for m in model_options() if models is None or m in models]
    all_cases = []
    for e in entries:
        all_cases += [c for c in _cases(e, quick) if c.model in chosen]
    own = engine is None
    engine = engine or Engine("serial", label="extremes")
    try:
        outcomes = _run_all(engine, all_cases, Path(out) / "cases")
    finally:
        if own:
            engine.close()
    records, k = [], 0
    for e in entries:
        for model in chosen:
            if model in e["skipped"]:
                records.append({"corner": e["label"], "model": model, "status": "skipped",
                                "reason": e["skipped"][model], "stiffened": e["stiffened"]})
                continue
            base, deeper, stiffer = outcomes[k:k + 3]
            k += 3
            records.append(judge(e, model, base, deeper, stiffer))
    return {"corners": [{"label": e["label"], "params": e["params"], "sets": e["sets"]}
                        for e in entries],
            "models": chosen, "records": records, "executor": engine.describe(),
            "wall_time_s": time.perf_counter() - t0}
