"""The paper's master curves fitted to our solutions, and the Hertz band of sigma_0.

Pure functions of arrays (SI units, Phi dimensionless).

- The reduced centre pressure sigma_0* = (sigma_0 - sigma_0H)/(sigma_0S - sigma_0H) against
  Phi* = (Phi - Phi_S)/Phi_H follows sigma_0* = (1 + Phi*)^-n with n = 3 ([P] eqs.
  Sig0PhiRed, MasterSig0Phi); Phi < Phi_S is the single-pillar plateau sigma_0* = 1.
  :func:`fit_thresholds` fits Phi_S and Phi_H to one curve sigma_0(Phi) as the paper does
  (n = 3), or n too; :func:`fit_common_exponent` fits one n to many curves, each with its own
  Phi_S and Phi_H.
- The reduced area A* = (A - A_S)/(A_H - A_S) = Phi^m with m = 0.7 ([P] eqs. APhiRed,
  MasterAPhi); :func:`fit_area_exponent` fits m.
- :func:`hertz_band_entry`: where sigma_0 comes within a band of the Hertz value.

References
----------
.. [P] R. Ledesma-Alonso et al., "Stress concentration in periodically rough hertzian
   contact: Hertz to soft-flat-punch transition" (the seed paper), Discussion.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

PAPER_EXPONENT = 3.0
PAPER_AREA_EXPONENT = 0.7


def reduced_pressure(sigma0, sigma0_hertz: float, sigma0_single: float):
    """sigma_0* = (sigma_0 - sigma_0H) / (sigma_0S - sigma_0H) ([P] eq. Sig0PhiRed)."""
    return (np.asarray(sigma0, float) - sigma0_hertz) / (sigma0_single - sigma0_hertz)


def master_curve(phi, phi_s: float, phi_h: float, exponent: float = PAPER_EXPONENT):
    """sigma_0*(Phi) = (1 + max(Phi - Phi_S, 0)/Phi_H)^-n ([P] eq. MasterSig0Phi)."""
    star = np.maximum(np.asarray(phi, float) - phi_s, 0.0) / phi_h
    return (1.0 + star) ** -exponent


def _initial_guess(phi, star) -> tuple[float, float]:
    """Phi_S: the last Phi still on the plateau (sigma_0* > 0.95); Phi_H: Phi - Phi_S where
    sigma_0* first falls below 1/8, the master curve's value at Phi* = 1."""
    on_plateau = phi[star > 0.95]
    phi_s = float(on_plateau.max()) if on_plateau.size else float(phi.min()) / 2.0
    below = phi[(star < 0.125) & (phi > phi_s)]
    phi_h = float(below.min() - phi_s) if below.size else float(phi.max())
    return phi_s, max(phi_h, 1e-3)


def fit_thresholds(phi, star, exponent: float | None = PAPER_EXPONENT) -> dict:
    """Least-squares fit of the master curve to one curve sigma_0*(Phi).

    Parameters
    ----------
    phi, star : array_like
        Surface fractions and reduced centre pressures of one (zeta, E_p/E_l).
    exponent : float or None
        n of the master curve; None fits it as well.

    Returns
    -------
    dict
        ``phi_s``, ``phi_h``, ``exponent`` and ``rms`` (root-mean-square residual in
        sigma_0*).  The residuals are in sigma_0* itself, as the paper compares curves on a
        linear sigma_0* axis; both thresholds are fitted in log so they stay positive.
    """
    phi, star = np.asarray(phi, float), np.asarray(star, float)
    phi_s0, phi_h0 = _initial_guess(phi, star)
    x0 = [math.log(phi_s0), math.log(phi_h0)] + ([] if exponent is not None else [0.0])

    def residual(x):
        n = exponent if exponent is not None else PAPER_EXPONENT * math.exp(x[2])
        return master_curve(phi, math.exp(x[0]), math.exp(x[1]), n) - star

    # The plateau makes the cost flat in Phi_S between two grid points: start from a few
    # places and keep the best.
    best = None
    for shift in (0.0, -0.5, 0.5):
        start = list(x0)
        start[0] += shift
        sol = least_squares(residual, start, method="lm", x_scale=1.0)
        if best is None or sol.cost < best.cost:
            best = sol
    n = exponent if exponent is not None else PAPER_EXPONENT * math.exp(best.x[2])
    return {"phi_s": math.exp(best.x[0]), "phi_h": math.exp(best.x[1]), "exponent": float(n),
            "rms": float(np.sqrt(np.mean(best.fun**2)))}


def fit_common_exponent(curves: list[tuple]) -> dict:
    """One exponent n for many curves (``(phi, star)`` pairs), each with its own Phi_S and
    Phi_H; starts from the per-curve fits at n = 3.  Returns ``exponent``, ``rms`` and the
    per-curve ``phi_s``, ``phi_h`` lists."""
    starts = [fit_thresholds(p, s) for p, s in curves]
    x0 = [0.0]
    for f in starts:
        x0 += [math.log(f["phi_s"]), math.log(f["phi_h"])]
    arrays = [(np.asarray(p, float), np.asarray(s, float)) for p, s in curves]

    def residual(x):
        n = PAPER_EXPONENT * math.exp(x[0])
        return np.concatenate([
            master_curve(p, math.exp(x[1 + 2 * k]), math.exp(x[2 + 2 * k]), n) - s
            for k, (p, s) in enumerate(arrays)])

    sol = least_squares(residual, x0, method="trf")
    return {"exponent": PAPER_EXPONENT * math.exp(sol.x[0]),
            "rms": float(np.sqrt(np.mean(sol.fun**2))),
            "phi_s": [math.exp(v) for v in sol.x[1::2]],
            "phi_h": [math.exp(v) for v in sol.x[2::2]]}


def exponent_profile(curves: list[tuple], exponents=(2.0, 3.0, 5.0, 10.0)) -> list[dict]:
    """The rms residual in sigma_0* of the master curve at each fixed n, every curve with its
    own fitted Phi_S and Phi_H: how sharply the data pick the exponent."""
    out = []
    for n in exponents:
        res = np.concatenate([
            master_curve(p, f["phi_s"], f["phi_h"], n) - np.asarray(s, float)
            for (p, s), f in ((c, fit_thresholds(*c, exponent=n)) for c in curves)])
        out.append({"exponent": float(n), "rms": float(np.sqrt(np.mean(res**2)))})
    return out


def reduced_area(area, radius: float, indentation: float, diameter: float):
    """A* = (A - A_S) / (A_H - A_S), A_H = pi R zeta, A_S = pi d^2 / 4 ([P] eq. APhiRed)."""
    a_h, a_s = math.pi * radius * indentation, math.pi * diameter**2 / 4.0
    return (np.asarray(area, float) - a_s) / (a_h - a_s)


def fit_area_exponent(phi, area_star, phi_range=(1e-2, 1.0)) -> dict:
    """m of A* = Phi^m: least squares of log A* = m log Phi (a line through the origin, as
    A* = 1 at Phi = 1) over the points with A* > 0 and Phi in ``phi_range`` ([P]: "accurate
    for Phi in [1e-2, 1]").  Returns ``exponent``, ``rms`` (in log10 A*) and ``points``."""
    phi, star = np.asarray(phi, float), np.asarray(area_star, float)
    keep = (star > 0) & (phi >= phi_range[0]) & (phi <= phi_range[1])
    if keep.sum() < 2:
        return {"exponent": None, "rms": None, "points": int(keep.sum())}
    x, y = np.log(phi[keep]), np.log(star[keep])
    m = float(np.dot(x, y) / np.dot(x, x))
    return {"exponent": m, "rms": float(np.sqrt(np.mean((y - m * x) ** 2)) / math.log(10)),
            "points": int(keep.sum())}


def hertz_band_entry(phi, sigma0, sigma0_hertz: float, band: float) -> dict:
    """Where sigma_0(Phi), falling from the single-pillar plateau, first comes within
    ``band`` (relative) of the Hertz value: the Phi at which sigma_0 = (1 + band) sigma_0H,
    interpolated linearly in (log Phi, log sigma_0) between the grid points around it.

    Returns ``phi`` (None when sigma_0 stays above the band over the grid; the first grid
    Phi when it starts inside), ``stays`` (False when sigma_0 leaves the band again below
    (1 - band) sigma_0H at a larger Phi: a soft Hooke layer makes the lattice more compliant
    than the Hertz half-space) and ``lowest`` (min sigma_0 / sigma_0H over Phi >= the entry).
    """
    phi, s = np.asarray(phi, float), np.asarray(sigma0, float) / sigma0_hertz
    order = np.argsort(phi)
    phi, s = phi[order], s[order]
    top = 1.0 + band
    inside = np.nonzero(s <= top)[0]
    if inside.size == 0:
        return {"phi": None, "stays": None, "lowest": float(s.min())}
    i = int(inside[0])
    if i == 0:
        entry = float(phi[0])
    else:
        x0, x1 = math.log(phi[i - 1]), math.log(phi[i])
        y0, y1 = math.log(s[i - 1]), math.log(s[i])
        entry = math.exp(x0 + (math.log(top) - y0) * (x1 - x0) / (y1 - y0))
    lowest = float(s[i:].min())
    return {"phi": entry, "stays": bool(lowest >= 1.0 - band), "lowest": lowest}
