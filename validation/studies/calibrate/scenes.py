"""Seeded scene sets of the calibration and of the planner's validation.

The paper's family ([P] Table 1: R = 2 mm, d = 4 um, h = 2 um, E_l = 1.6 MPa, every
nu = 0.5) is sampled by a Latin hypercube in log10 Phi over [2.3e-3, 0.82], log10 zeta over
[0.005, 0.5] um and log10 E_p/E_l over [1e-3, 1e6], with the paper's E_s = E_p; a second,
smaller sample keeps the substrate at the lens's modulus (E_s = E_l), so that pillars much
softer than both half-spaces are measured too.  :func:`drawn_scenes` draws the scenes a
filter accepts (the planner validation's lattices whose fem-3d ladder fits the machine).
Calibration and validation draw different seeds: the validation is out of sample.
"""

from __future__ import annotations

import math

import numpy as np

from pillar_xval.scenes import InputError, load_scene

__all__ = ["PAPER_RANGES", "drawn_scenes", "flat_scenes", "gecit_scenes", "lattice_scenes",
           "punch_scenes"]

BASE = "paper-fig3-sparse"
E_LENS = 1.6e6
# [P] Table 1 ranges: log10 of Phi, zeta (um) and E_p / E_l.
PAPER_RANGES = {"phi": (np.log10(2.3e-3), np.log10(0.82)),
                "zeta_um": (np.log10(0.005), np.log10(0.5)),
                "ratio": (-3.0, 6.0)}


def _scene(phi: float, zeta_um: float, ratio: float, substrate: str, tag: str):
    e_p = E_LENS * ratio
    e_s = e_p if substrate == "pillars" else E_LENS
    sets = [f"pillars.surface_fraction={phi!r}", f"load.indentation_um={zeta_um!r}",
            f"pillars.E_Pa={e_p!r}", f"substrate.E_Pa={e_s!r}"]
    return {"name": tag, "family": f"E_s = {'E_p' if substrate == 'pillars' else 'E_l'}",
            "phi": phi, "zeta_um": zeta_um, "ratio": ratio, "sets": sets,
            "scene": load_scene(BASE, sets).replace(name=tag)}


def lattice_scenes(n: int, seed: int, substrate: str = "pillars", prefix: str = "s") -> list:
    """``n`` scenes of the paper's family by a seeded Latin hypercube (see the module
    docstring); ``substrate`` is ``"pillars"`` (E_s = E_p) or ``"lens"`` (E_s = E_l)."""
    from scipy.stats import qmc

    u = qmc.LatinHypercube(d=3, seed=seed).random(n)
    return [_unit_scene(row, PAPER_RANGES, substrate, f"{prefix}{i:02d}")
            for i, row in enumerate(u)]


def _unit_scene(row, ranges: dict, substrate: str, tag: str) -> dict:
    """The scene at a point ``row`` of the unit cube, mapped to log10 of ``ranges`` (Phi,
    zeta in um, E_p/E_l), each value rounded to four digits."""
    keys = ("phi", "zeta_um", "ratio")
    lo = np.array([ranges[k][0] for k in keys])
    hi = np.array([ranges[k][1] for k in keys])
    phi, zeta, ratio = 10.0 ** (lo + np.asarray(row) * (hi - lo))
    return _scene(float(f"{phi:.4g}"), float(f"{zeta:.4g}"), float(f"{ratio:.4g}"),
                  substrate, tag)


def drawn_scenes(n: int, seed: int, keep, ranges=None, substrate: str = "pillars",
                 prefix: str = "l", max_draws: int = 8192) -> list:
    """The first ``n`` scenes of the paper's family that ``keep(scene)`` accepts, drawn along
    a scrambled Halton sequence (``seed``) in log10 of ``ranges`` (default
    :data:`PAPER_RANGES`): a low-discrepancy sequence, so the first ``n`` accepted spread
    evenly over the accepted region whatever share of the box it is.  InputError naming ``n``
    when ``max_draws`` points do not yield ``n``."""
    from scipy.stats import qmc

    sequence = qmc.Halton(d=3, scramble=True, seed=seed)
    out, drawn = [], 0
    while len(out) < n:
        if drawn >= max_draws:
            raise InputError(f"{n} scenes: only {len(out)} of {max_draws} drawn (seed {seed}) "
                             "are accepted; ask for fewer")
        for row in sequence.random(256):
            drawn += 1
            s = _unit_scene(row, ranges or PAPER_RANGES, substrate, f"{prefix}{len(out):02d}")
            if keep(s["scene"]):
                out.append(s)
                if len(out) == n:
                    break
    return out


def flat_scenes(zeta_over_r=(1.5e-4, 1e-2, 0.1, 0.4)) -> list:
    """The Hertz preset at several zeta / R (the only length ratio of a flat scene)."""
    out = []
    for i, ratio in enumerate(zeta_over_r):
        zeta_um = ratio * 2000.0
        sets = [f"load.indentation_um={zeta_um!r}"]
        out.append({"name": f"flat{i}", "family": "flat", "zeta_um": zeta_um, "sets": sets,
                    "scene": load_scene("hertz", sets).replace(name=f"flat{i}")})
    return out


# The Gecit grid's indentations (um): the preset's 0.3 and down to the bottom of the
# sample's range (PAPER_RANGES).  The Hooke pillar's sigma0 error depends on it: for
# E_p = 1e3 E_l on a substrate as soft as the lens (h/d = 0.5) it is -1.0 % at 0.3 um,
# -7.8 % at 0.03 um and -28 % at 0.005 um; for E_s = E_p = 100 E_l, -1.4, -1.3 and -0.8 %.
GECIT_ZETAS_UM = (0.3, 0.05, 0.015, 0.005)


def gecit_scenes(ratios=(1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3, math.inf),
                 aspects=(0.25, 0.5, 1.0), substrates=None, zetas_um=(None,)) -> list:
    """The Gecit-like study on a full grid of E_p/E_l x E_s/E_l x h/d (x zeta) on the
    single-pillar preset (``substrates``, as ratios E_s/E_l, default the same as ``ratios``;
    ``inf`` is a rigid body, which fem-axisym represents exactly where a finite 1e6 contrast
    can miss its linear residual; ``zetas_um``, the indentations, None the preset's): rows for
    :func:`validation.studies.gecit.gecit_study` (``ratio``, ``aspect``, ``zeta_um``,
    ``scene``).  A full grid, so that the paper's diagonal E_s = E_p and a stiff substrate
    are both interpolated along measured lines."""
    def modulus(part, ratio):
        return f"{part}.rigid=true" if math.isinf(ratio) else f"{part}.E_Pa={E_LENS * ratio!r}"

    out = []
    for zeta in zetas_um:
        for aspect in aspects:
            for sub in (ratios if substrates is None else substrates):
                for ratio in ratios:
                    sets = [modulus("pillars", ratio), modulus("substrate", sub),
                            f"pillars.height_um={4.0 * aspect!r}"]
                    if zeta is not None:
                        sets.append(f"load.indentation_um={zeta!r}")
                    scene = load_scene("single-pillar", sets)
                    out.append({"ratio": ratio, "aspect": aspect, "substrate_ratio": sub,
                                "zeta_um": scene.indentation_m * 1e6, "scene": scene})
    return out


def punch_scenes(zetas_um=(0.005, 0.015, 0.05, 0.15, 0.5, 1.5),
                 ratios=(1e-3, 1e-1, 1.0, 10.0, 1e3, 1e6)) -> list:
    """Single pillars over zeta and E_p / E_l (both substrates): where the flat punch of the
    spring model meets the curved lens.  Only the (cheap) dense BEM runs on them."""
    out = []
    for substrate in ("pillars", "lens"):
        for zeta in zetas_um:
            for ratio in ratios:
                if substrate == "lens" and ratio == 1.0:
                    continue  # the same scene as with E_s = E_p
                s = _scene(2.3e-3, zeta, ratio, substrate, f"p{len(out):02d}")
                out.append(s)
    return out
