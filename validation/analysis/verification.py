"""Solution verification: observed order, Richardson extrapolation and the grid convergence
index (GCI) of Roache, in the procedure of Celik et al.

Every function here works on plain numbers: ``h`` is a representative cell size (any length
unit, or dimensionless; only ratios matter) and ``f`` a computed quantity in its own unit.
Nothing returns NaN or inf.  A sequence that does not allow an estimate (oscillating,
converged to round-off, diverging) gives ``None`` in the affected fields and says why in
``status``; for those cases ``fallback_uncertainty`` is a conservative band (Fs = 3 times the
largest difference between the three solutions), so that a caller always has a number to
set beside a difference, and knows from ``status`` that it is not a GCI.

References
----------
.. [R] P. J. Roache, *Verification and Validation in Computational Science and Engineering*,
   Hermosa, 1998, ch. 5 (GCI, Fs = 1.25 with three grids, 3 with two).
.. [C] I. B. Celik et al., "Procedure for estimation and reporting of uncertainty due to
   discretization in CFD applications", J. Fluids Eng. 130 (2008) 078001 (general ratio,
   the equation for p, oscillatory convergence).
.. [N] NASA NPARC Alliance, "Examining spatial (grid) convergence" (worked example used by the
   unit tests: p = 1.7862, f_exact = 0.971300, GCI_12 = 0.1031 %, GCI_23 = 0.3562 %).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

FS_THREE_GRIDS = 1.25  # [R]: safety factor when the order is observed (three or more grids)
FS_TWO_GRIDS = 3.0     # [R]: safety factor when the order is assumed (two grids)
# Differences below this fraction of |f| are round-off, not discretisation error: a double
# carries ~16 digits, solvers converge to ~1e-10 relative.
RTOL_ROUNDOFF = 1e-10
# GCI_23 / (r^p GCI_12) within this distance of 1 counts as the asymptotic range.
ASYMPTOTIC_TOL = 0.1

__all__ = [
    "FS_THREE_GRIDS", "FS_TWO_GRIDS", "GCIResult", "OrderFit", "gci_three", "gci_two",
    "loglog_order", "observed_order_lsq", "refinement_ratios", "study",
]


@dataclass
class GCIResult:
    """GCI of one quantity from the finest grids (index 1 = finest).

    Attributes
    ----------
    h, f : list of float
        Cell sizes (fine to coarse) and values (unit of the quantity).
    ratios : list of float
        r21 = h2/h1 and (three grids) r32 = h3/h2.
    order : float or None
        Observed order p (``None`` when it cannot be estimated; two grids: the assumed order).
    f_exact : float or None
        Richardson estimate f1 + (f1 - f2)/(r21^p - 1) (unit of f).
    gci_fine, gci_coarse : float or None
        GCI_12 and GCI_23 as fractions (multiply by 100 for %), relative to f1 and f2.
    uncertainty : float or None
        gci_fine * |f1|, the band on f1 in the unit of f (defined even when f1 = 0).
    asymptotic_ratio : float or None
        GCI_23 / (r21^p GCI_12); 1 in the asymptotic range.
    fallback_uncertainty : float
        Always finite: ``uncertainty`` when ``status == 'ok'``, otherwise Fs = 3 times the
        spread of the solutions (unit of f), as [R] advises for oscillating sequences.
    status : str
        ``ok``, ``two-grid``, ``oscillatory``, ``round-off``, ``divergent``, ``fine-pair-equal``
        or ``order-out-of-range``.
    """

    h: list
    f: list
    ratios: list
    fs: float
    status: str
    order: float | None = None
    f_exact: float | None = None
    gci_fine: float | None = None
    gci_coarse: float | None = None
    uncertainty: float | None = None
    asymptotic_ratio: float | None = None
    asymptotic: bool | None = None
    fallback_uncertainty: float = 0.0
    note: str = ""

    def to_dict(self) -> dict:
        return asdict(self)


def refinement_ratios(h) -> np.ndarray:
    """r_{k+1,k} = h_{k+1}/h_k for sizes sorted fine to coarse; refuses r <= 1."""
    h = np.asarray(h, dtype=float)
    if np.any(~np.isfinite(h)) or np.any(h <= 0):
        raise ValueError(f"cell sizes {h.tolist()}: must be finite and > 0")
    r = h[1:] / h[:-1]
    if np.any(r <= 1.0 + 1e-12):
        raise ValueError(f"cell sizes {h.tolist()}: must grow strictly from fine to coarse")
    return r


def _observed_order(r21: float, r32: float, eps21: float, eps32: float) -> float | None:
    """Order p of a monotone sequence (eps32/eps21 > 0) with ratios r21, r32.

    Solves Celik's eq. p ln r21 = ln(eps32/eps21) + q(p), q = ln((r21^p - 1)/(r32^p - 1)),
    i.e. G(p) = p ln r21 + ln((r32^p - 1)/(r21^p - 1)) = ln(eps32/eps21), by bracketing
    (G increases with p) rather than by Celik's fixed-point iteration, which can cycle when
    the two ratios differ.  Returns a value <= 0 when no positive order fits (divergence),
    None when p would exceed 60.
    """
    target = math.log(eps32 / eps21)
    if abs(r21 - r32) < 1e-12 * r21:
        return target / math.log(r21)  # constant ratio: q = 0 and the formula is explicit
    l21, l32 = math.log(r21), math.log(r32)

    def g(p: float) -> float:
        return p * l21 + math.log(math.expm1(p * l32) / math.expm1(p * l21)) - target

    lo, hi = 1e-9, 60.0
    if g(lo) >= 0:
        return 0.0
    if g(hi) <= 0:
        return None
    from scipy.optimize import brentq  # here: scipy.optimize costs 0.3 s at import

    return brentq(g, lo, hi, xtol=1e-14, rtol=1e-14)


def gci_three(h, f, fs: float = FS_THREE_GRIDS) -> GCIResult:
    """GCI from three grids, finest first ([C] steps 1-5).

    Parameters
    ----------
    h : sequence of 3 floats
        Cell sizes h1 < h2 < h3 (any length unit); ratios need not be equal.
    f : sequence of 3 floats
        Solutions on those grids (unit of the quantity).
    fs : float
        Safety factor (1.25 for three grids [R]).

    Returns
    -------
    GCIResult
        ``status == 'ok'`` with order, Richardson estimate and GCI_12, GCI_23, or ``None``
        fields with a status string for sequences that admit no estimate.
    """
    h = [float(x) for x in h]
    f = [float(x) for x in f]
    if len(h) != 3 or len(f) != 3:
        raise ValueError("gci_three needs exactly three cell sizes and three values")
    if not all(math.isfinite(x) for x in f):
        raise ValueError(f"values {f}: must be finite")
    r21, r32 = (float(x) for x in refinement_ratios(h))
    f1, f2, f3 = f
    eps21, eps32 = f2 - f1, f3 - f2
    scale = max(abs(f1), abs(f2), abs(f3))
    spread = max(f) - min(f)
    out = GCIResult(h=h, f=f, ratios=[r21, r32], fs=fs, status="ok",
                    fallback_uncertainty=FS_TWO_GRIDS * spread)
    tiny = RTOL_ROUNDOFF * scale
    if abs(eps21) <= tiny and abs(eps32) <= tiny:
        out.status = "round-off"
        out.note = "all three solutions agree to round-off; the discretisation error is nil"
        out.f_exact, out.uncertainty, out.fallback_uncertainty = f1, spread, spread
        return out
    if abs(eps21) <= tiny:
        out.status = "fine-pair-equal"
        out.note = "the two finest solutions agree to round-off while the coarse one differs"
        return out
    if abs(eps32) <= tiny:
        out.status = "divergent"
        out.note = "the coarse pair agrees but the fine pair differs: not converging"
        return out
    if eps32 / eps21 < 0:
        out.status = "oscillatory"
        out.note = "differences change sign (oscillatory convergence): no order is observed"
        return out
    p = _observed_order(r21, r32, eps21, eps32)
    if p is None:
        out.status = "order-out-of-range"
        out.note = "the observed order would exceed 60: differences collapse too fast"
        return out
    if p <= 0:
        out.status = "divergent"
        out.note = f"observed order {p:.3g} <= 0: differences grow under refinement"
        return out
    _fill_estimates(out, p, fs)
    return out


def _fill_estimates(out: GCIResult, p: float, fs: float) -> None:
    f = out.f
    r21 = out.ratios[0]
    f1, f2 = f[0], f[1]
    rp21 = r21**p
    if not math.isfinite(rp21) or rp21 - 1.0 <= 0:
        out.status = "divergent"
        out.note = f"r^p = {rp21:g} is not usable"
        return
    out.order = p
    out.f_exact = f1 + (f1 - f2) / (rp21 - 1.0)
    out.uncertainty = fs * abs(f1 - f2) / (rp21 - 1.0)
    out.fallback_uncertainty = out.uncertainty
    out.gci_fine = out.uncertainty / abs(f1) if f1 != 0 else None
    if len(f) == 3:
        r32 = out.ratios[1]
        rp32 = r32**p
        f3 = f[2]
        out.gci_coarse = fs * abs((f2 - f3) / f2) / (rp32 - 1.0) if f2 != 0 else None
        if out.gci_fine and out.gci_coarse is not None:
            out.asymptotic_ratio = out.gci_coarse / (rp21 * out.gci_fine)
            out.asymptotic = abs(out.asymptotic_ratio - 1.0) <= ASYMPTOTIC_TOL
    if out.gci_fine is None:
        out.note = (out.note + " f1 = 0: relative GCI undefined, see uncertainty").strip()


def gci_two(h, f, order: float, fs: float = FS_TWO_GRIDS) -> GCIResult:
    """GCI from two grids with an assumed (formal) order ``order`` ([R]: Fs = 3).

    Parameters
    ----------
    h : sequence of 2 floats
        Cell sizes h1 < h2.
    f : sequence of 2 floats
        Solutions (unit of the quantity).
    order : float
        Assumed order of accuracy p > 0.
    """
    h = [float(x) for x in h]
    f = [float(x) for x in f]
    if len(h) != 2 or len(f) != 2:
        raise ValueError("gci_two needs exactly two cell sizes and two values")
    if not order > 0:
        raise ValueError(f"order = {order}: must be > 0")
    r21 = float(refinement_ratios(h)[0])
    out = GCIResult(h=h, f=f, ratios=[r21], fs=fs, status="two-grid",
                    fallback_uncertainty=fs * abs(f[1] - f[0]),
                    note=f"order assumed = {order:g}, not observed")
    _fill_estimates(out, float(order), fs)
    return out


@dataclass
class OrderFit:
    """Least-squares fit log(err) = log(C) + p log(h) over ``n`` levels."""

    order: float | None
    log_constant: float | None
    r_squared: float | None
    n: int
    status: str

    def to_dict(self) -> dict:
        return asdict(self)


def loglog_order(h, err) -> OrderFit:
    """Fit err = C h^p by least squares in log-log (a rate over >= 3 levels: PHYSICS.md,
    "Verification").

    Parameters
    ----------
    h : sequence of float
        Cell sizes (any unit).
    err : sequence of float
        Errors (absolute values are used; zeros are dropped as round-off).
    """
    h = np.asarray(h, dtype=float)
    e = np.abs(np.asarray(err, dtype=float))
    keep = np.isfinite(e) & (e > 0) & np.isfinite(h) & (h > 0)
    n = int(keep.sum())
    if n < 3:
        return OrderFit(None, None, None, n, f"too few usable levels ({n} < 3)")
    x, y = np.log(h[keep]), np.log(e[keep])
    if np.ptp(x) == 0:
        return OrderFit(None, None, None, n, "all cell sizes equal")
    p, c = np.polyfit(x, y, 1)
    resid = y - (p * x + c)
    ss = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum(resid**2)) / ss if ss > 0 else 1.0
    return OrderFit(float(p), float(c), r2, n, "ok")


def observed_order_lsq(h, f, f_ref: float | None = None) -> OrderFit:
    """Order over all levels: fit |f - f_ref| against h, or, without a reference, the
    differences |f_{k+1} - f_k| against the finer size h_k (these scale as h_k^p when the
    ratio is constant; for mildly varying ratios the fit is an approximation)."""
    h = np.asarray(h, dtype=float)
    f = np.asarray(f, dtype=float)
    order = np.argsort(h)
    h, f = h[order], f[order]
    if f_ref is not None:
        return loglog_order(h, f - f_ref)
    diffs = np.diff(f)
    fit = loglog_order(h[:-1], diffs)
    nonzero = diffs[diffs != 0]
    if fit.status == "ok" and np.any(np.sign(nonzero) != np.sign(nonzero[0])):
        fit.status = "oscillatory: |differences| fitted, the order is indicative only"
    return fit


def study(h, f) -> dict:
    """Everything about one quantity on N >= 2 levels (any order of ``h``).

    Returns a JSON-ready dict: ``gci`` from the three finest levels (two-grid GCI with the
    least-squares or no order when N = 2), ``lsq`` over all levels (differences), and the
    levels sorted fine to coarse.
    """
    h = np.asarray(h, dtype=float)
    f = np.asarray(f, dtype=float)
    if len(h) != len(f) or len(h) < 2:
        raise ValueError("a convergence study needs at least two levels")
    idx = np.argsort(h)
    h, f = h[idx], f[idx]
    if len(h) >= 3:
        gci = gci_three(h[:3], f[:3])
    else:
        gci = GCIResult(h=h.tolist(), f=f.tolist(), ratios=refinement_ratios(h).tolist(),
                        fs=FS_TWO_GRIDS, status="two-grid",
                        fallback_uncertainty=FS_TWO_GRIDS * abs(f[1] - f[0]),
                        note="two levels: no observed order; band = 3 |f1 - f2|")
    lsq = observed_order_lsq(h, f)
    return {"h": h.tolist(), "f": f.tolist(), "gci": gci.to_dict(), "lsq": lsq.to_dict()}
