"""The paper's claims behind Figs. 4-8, checked on each pillar model's figures.

:func:`claim_rows` takes one study document per pillar model (``{"hooke": doc, "elastic":
doc}``, the documents :func:`~.run.run_figures` builds) and returns one row per claim: what
the paper says, the criterion, and per pillar model the value and whether the claim holds
(True/False; None when the data cannot decide, e.g. no curve at zeta = 0.3 um).  Every
criterion is a pure function of the document's numbers, so a constructed document can make
each claim hold or fail (tests/test_figures_pillars.py).

The criteria, and why these tolerances:

- Fig. 5, sigma_0S on eq. S0BvsE ("excellent agreement"): every single-pillar sigma_0 within
  2 % of the spring model.  The spring model ignores the lens sag over the pillar top
  (a^2 (1 + s)/(R zeta) <= 1.2 % at zeta = 0.3 um) and the figures' model is within 0.6 %
  (tests/test_figures.py, RTOL_SPRING_MODEL).
- Phi_S and Phi_H at zeta = 0.3 um (Fig. 4a's caption: Phi_S in [0.0094, 0.0135], Phi_H in
  [0.306, 0.38], hard to soft): every value (fitted, exact or the Hertz band) within the
  paper's interval widened by 20 % on each side: the paper reads its thresholds off fits in
  which Phi_H trades against the exponent, and the exact Phi_S sits 11 % below [P]'s closed
  form (the ring touches at its rim, thresholds.py).
- The master curve sigma_0* = (1 + Phi*)^-3: the best common exponent within 3 +- 0.5, and
  the data collapse: rms of sigma_0* about (1 + Phi*)^-3 (Phi_S, Phi_H fitted per curve) at
  most 0.05, 5 % of the curve's span from 1 to 0.
- A* = Phi^0.7: the fitted exponent within 0.7 +- 0.1.
- Figs. 7-8 (phase diagram): both thresholds decrease as zeta/h grows, for every E_p/E_l
  (each step may rise by at most 5 %, the fits' scatter); Phi_S an order of magnitude below
  Phi_H (Phi_H / Phi_S >= 10 on every curve); softer materials shift Phi_H up
  (Phi_H(softest) > Phi_H(hardest) at every zeta).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from pillar_xval.outcome import write_atomic

from .fits import PAPER_AREA_EXPONENT, PAPER_EXPONENT

__all__ = ["CLAIMS", "claim_rows", "write_claims_csv"]

ZETA_FIG4_UM = 0.3
SPRING_MODEL_RTOL = 0.02
PAPER_PHI_S = (0.0094, 0.0135)
PAPER_PHI_H = (0.306, 0.38)
THRESHOLD_WIDEN = 0.20
EXPONENT_TOL = 0.5
COLLAPSE_RMS = 0.05
AREA_EXPONENT_TOL = 0.1
MONOTONE_RISE = 0.05
SEPARATION = 10.0


def _at_fig4_zeta(doc: dict) -> list[dict]:
    return [c for c in doc.get("fig4a_curves", [])
            if abs(c["zeta_um"] - ZETA_FIG4_UM) < 1e-9]


def _within_widened(values, interval) -> tuple[str, bool | None]:
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return "no value", None
    lo, hi = interval
    ok = all(lo * (1 - THRESHOLD_WIDEN) <= x <= hi * (1 + THRESHOLD_WIDEN) for x in v)
    return f"[{min(v):.3g}, {max(v):.3g}]", ok


def _fig5(doc):
    rows = doc.get("fig5") or []
    if not rows:
        return "no single-pillar point", None
    dev = [r["sigma0_Pa"] / r["closed_form_Pa"] - 1.0 for r in rows]
    worst = max(dev, key=abs)
    return (f"{100 * min(dev):+.1f} % to {100 * max(dev):+.1f} %",
            abs(worst) <= SPRING_MODEL_RTOL)


def _phi_s_fit(doc):
    return _within_widened([c["phi_s_fit"] for c in _at_fig4_zeta(doc)], PAPER_PHI_S)


def _phi_s_exact(doc):
    ex = [e["phi_s"] for e in doc["thresholds"]["exact"]
          if abs(e["zeta_um"] - ZETA_FIG4_UM) < 1e-9]
    return _within_widened(ex, PAPER_PHI_S)


def _phi_h_fit(doc):
    return _within_widened([c["phi_h_fit"] for c in _at_fig4_zeta(doc)], PAPER_PHI_H)


def _phi_h_band(doc):
    curves = _at_fig4_zeta(doc)
    if curves and any(c["phi_h_band"] is None for c in curves):
        n = sum(c["phi_h_band"] is None for c in curves)
        text, _ = _within_widened([c["phi_h_band"] for c in curves], PAPER_PHI_H)
        return f"{text}; {n} of {len(curves)} curves never within the band", False
    return _within_widened([c["phi_h_band"] for c in curves], PAPER_PHI_H)


def _exponent(doc):
    n = doc["thresholds"]["common_exponent"]["exponent"]
    if n is None or not math.isfinite(n):
        return "no fit", None
    return f"{n:.2f}", abs(n - PAPER_EXPONENT) <= EXPONENT_TOL


def _collapse(doc):
    ce = doc["thresholds"]["common_exponent"]
    rms = ce.get("rms_n3")
    if rms is None or not math.isfinite(rms):
        return "no fit", None
    return f"rms {rms:.3f} at n = 3 ({ce['rms']:.3f} at the best n)", rms <= COLLAPSE_RMS


def _area(doc):
    m = doc["thresholds"]["area_exponent"]["exponent"]
    if m is None or not math.isfinite(m):
        return "no fit", None
    return (f"{m:.2f} (rms {doc['thresholds']['area_exponent']['rms']:.2f} decades)",
            abs(m - PAPER_AREA_EXPONENT) <= AREA_EXPONENT_TOL)


def _by_ratio(doc) -> dict:
    out = {}
    for c in doc["thresholds"]["curves"]:
        out.setdefault(c["ratio"], []).append(c)
    return {r: sorted(cs, key=lambda c: c["zeta_um"]) for r, cs in out.items()}


def _decreasing(doc):
    worst, where = 0.0, ""
    groups = _by_ratio(doc)
    if not groups or all(len(cs) < 2 for cs in groups.values()):
        return "fewer than two indentations", None
    for ratio, cs in groups.items():
        for key, name in (("phi_s_fit", "Phi_S"), ("phi_h_fit", "Phi_H")):
            v = np.array([c[key] for c in cs], float)
            if len(v) < 2:
                continue
            with np.errstate(divide="ignore", invalid="ignore"):
                rise = np.where(v[:-1] > 0, v[1:] / v[:-1] - 1.0, np.inf)
            k = int(np.argmax(rise))
            if rise[k] > worst:
                worst, where = float(rise[k]), (f"{name} at E_p/E_l = {ratio:g}, zeta "
                                                f"{cs[k]['zeta_um']:g} -> "
                                                f"{cs[k + 1]['zeta_um']:g} um")
    text = "every step down" if worst <= 0 else f"largest rise {100 * worst:+.0f} % ({where})"
    return text, worst <= MONOTONE_RISE


def _separation(doc):
    ratios = [c["phi_h_fit"] / c["phi_s_fit"] if c["phi_s_fit"] > 0 else math.inf
              for c in doc["thresholds"]["curves"]]
    if not ratios:
        return "no curve", None
    return f"Phi_H / Phi_S >= {min(ratios):.3g}", min(ratios) >= SEPARATION


def _soft_shift(doc):
    groups = _by_ratio(doc)
    if len(groups) < 2:
        return "one E_p/E_l", None
    soft, hard = groups[min(groups)], groups[max(groups)]
    hz = {c["zeta_um"]: c["phi_h_fit"] for c in hard}
    pairs = [(c["phi_h_fit"], hz[c["zeta_um"]]) for c in soft if c["zeta_um"] in hz]
    if not pairs:
        return "no common indentation", None
    up = sum(s > h for s, h in pairs)
    return (f"Phi_H(E_p/E_l = {min(groups):g}) > Phi_H({max(groups):g}) at {up} of "
            f"{len(pairs)} zeta", up == len(pairs))


# (key, figure, the paper's claim, criterion, check)
CLAIMS = (
    ("fig5_spring_model", "Fig. 5", "sigma_0S follows eq. S0BvsE (\"excellent agreement\")",
     f"every sigma_0S within {SPRING_MODEL_RTOL:.0%} of eq. S0BvsE", _fig5),
    ("phi_s_fit", "Fig. 4a", "Phi_S in [0.0094, 0.0135] at zeta = 0.3 um (fitted)",
     f"every fitted Phi_S in the paper's range widened by {THRESHOLD_WIDEN:.0%}", _phi_s_fit),
    ("phi_s_exact", "Fig. 4a, 7a", "Phi_S in [0.0094, 0.0135] at zeta = 0.3 um (one pillar "
     "alone; ours: bisection)",
     f"every exact Phi_S in the paper's range widened by {THRESHOLD_WIDEN:.0%}", _phi_s_exact),
    ("phi_h_fit", "Fig. 4a", "Phi_H in [0.306, 0.38] at zeta = 0.3 um (fitted)",
     f"every fitted Phi_H in the paper's range widened by {THRESHOLD_WIDEN:.0%}", _phi_h_fit),
    ("phi_h_band", "Fig. 4a", "above Phi_H sigma_0 is Hertz's (ours: within the Hertz band)",
     f"every curve enters the band, at a Phi in the paper's range widened by "
     f"{THRESHOLD_WIDEN:.0%}", _phi_h_band),
    ("master_exponent", "Fig. 6a", "sigma_0* = (1 + Phi*)^-n with n = 3",
     f"best common n within 3 +- {EXPONENT_TOL:g}", _exponent),
    ("master_collapse", "Fig. 6a", "the curves collapse on (1 + Phi*)^-3",
     f"rms of sigma_0* about (1 + Phi*)^-3 <= {COLLAPSE_RMS:g}", _collapse),
    ("area_exponent", "Fig. 6b", "A* = Phi^0.7",
     f"fitted exponent within 0.7 +- {AREA_EXPONENT_TOL:g}", _area),
    ("thresholds_decrease", "Fig. 7", "Phi_S and Phi_H decrease as zeta/h grows",
     f"for every E_p/E_l no step rises by more than {MONOTONE_RISE:.0%}", _decreasing),
    ("thresholds_separated", "Fig. 8", "Phi_S an order of magnitude below Phi_H",
     f"Phi_H / Phi_S >= {SEPARATION:g} on every curve", _separation),
    ("soft_shift", "Figs. 7-8", "softer materials shift Phi_H to larger values",
     "Phi_H of the softest E_p/E_l above the hardest's at every zeta", _soft_shift),
)


def claim_rows(docs: dict) -> list[dict]:
    """One row per claim: ``key``, ``figure``, ``claim``, ``criterion`` and per pillar model
    of ``docs`` a ``{"value": text, "holds": True | False | None}``."""
    rows = []
    for key, fig, claim, criterion, check in CLAIMS:
        row = {"key": key, "figure": fig, "claim": claim, "criterion": criterion}
        for pillars, doc in docs.items():
            try:
                value, holds = check(doc)
            except (KeyError, TypeError, ValueError, ZeroDivisionError) as exc:
                value, holds = f"not computed ({type(exc).__name__})", None
            row[pillars] = {"value": value, "holds": holds}
        rows.append(row)
    return rows


def verdict(holds) -> str:
    return {True: "yes", False: "no"}.get(holds, "undecided")


def write_claims_csv(out: Path, rows: list[dict], variants, grid: str = "full") -> Path:
    """``claims.csv``: one line per (claim, pillar model): key, figure, pillars, grid (the
    figures' grid it was judged on: ``full``, or ``quick``, the coarse one of --quick),
    value, holds (yes / no / undecided), claim, criterion."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["key", "figure", "pillars", "grid", "value", "holds", "claim", "criterion"])
    for r in rows:
        for v in variants:
            w.writerow([r["key"], r["figure"], v, grid, r[v]["value"], verdict(r[v]["holds"]),
                        r["claim"], r["criterion"]])
    return write_atomic(Path(out) / "claims.csv", buf.getvalue())
