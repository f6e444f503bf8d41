"""The lattice study's grid: its constants, the lattice point and the cases of a point."""

from __future__ import annotations

from dataclasses import dataclass

from pillar_xval.scenes import InputError, Scene, load_scene

from ...engine import Case
from ...registry import reference_model

PHIS = (0.03, 0.1, 0.2, 0.4)
RATIOS = (0.1, 1.0, 10.0, 1e6)
ZETA_UM = 0.3
E_LENS = 1.6e6
FEM_MODEL, BEM_MODEL = reference_model("lattice"), "bem-fft"
# The two BEMs: the paper's Hooke pillar (the model's default, so its cases keep their keys)
# and the elastic pillar.
HOOKE, ELASTIC = "hooke", "elastic"
BEM_OPTIONS = {HOOKE: {}, ELASTIC: {"pillars": "elastic"}}
BEM_NAMES = {HOOKE: "Hooke BEM", ELASTIC: "elastic BEM"}
# fem-3d: sqrt(2) per level (x 2.8 unknowns); 1.41 is 2-4 minutes on the Phi = 0.4 scene.
FEM_LEVELS = (2.83, 2.0, 1.41)
# bem-fft: cells per diameter, ratio 2; the FFT model converges at order ~1 (smooth edge
# cells) where the dense model's edge-cut pattern makes its order wobble.  Both BEMs climb it.
BEM_LEVELS = (16, 32, 64)
QUICK_FEM_LEVELS, QUICK_BEM_LEVELS = (4.0, 2.83), (8, 16)
# The dense elastic-pillar BEM at the planner's rungs (its candidates "bem P=11 elastic",
# "bem P=15 elastic" and "bem P=21 elastic", same options): single levels, not a ladder; each
# is set against fem-3d's estimate, so the planner reads its error in a lattice directly
# (calibrate).  P = 15 and the elastic bem-fft's single levels FFT_RUNGS, between its ladder's
# levels, put the elastic rungs as close in time as the Hooke BEMs' (1.8-2.6x a step, against
# 3.6x from P = 11 to 21 and 4x from N = 16 to 32): a plan one rung finer than needed then
# stays near 2x of the cheapest.
DENSE_MODEL = "bem"
DENSE_LEVELS = (11, 15, 21)
QUICK_DENSE_LEVELS = (11,)
DENSE_OPTIONS = {"cells": "covered", "pillars": ELASTIC}
FFT_RUNGS = (24, 48)
QUICK_FFT_RUNGS = ()

# Substrate conventions: the lens material (the grid) or the pillars' (the paper's Table 1).
LENS, PILLAR = "E_s = E_l", "E_s = E_p"
CONVENTIONS = (LENS, PILLAR)
# The paper's convention on four scenes (Phi, E_p/E_l).  E_p/E_l = 1 would repeat an E_s = E_l
# scene and 1e6 makes the substrate rigid too (both BEMs then agree by construction: no pillar
# compliance is left), so the soft (0.1) and stiff (10) pillars; Phi = 0.2 and 0.4 load the most
# pillars (19-37 at zeta = 0.3 um), where the one approximation left in the elastic BEM (the
# pillars couple through a half-space at the plane of their tops, not through a substrate at
# depth h) matters most, and at E_s = E_p the substrate is as soft or stiff as the pillars, so
# the substrate's share of the compliance differs from the grid's by the same factor.
PAPER_SCENES = ((0.2, 0.1), (0.2, 10.0), (0.4, 0.1), (0.4, 10.0))

# The centre pillar's top profile along theta = 0 at r = x d/2 (r < 0.9 d/2).
PROFILE_POINTS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85)


@dataclass(frozen=True)
class LatticePoint:
    surface_fraction: float
    ratio: float  # E_p / E_l
    substrate: str = LENS  # the convention: E_s = E_l or E_s = E_p
    zeta_um: float = ZETA_UM  # the indentation, micrometres

    def __post_init__(self):
        if self.substrate not in CONVENTIONS:
            raise InputError(f"substrate convention {self.substrate!r}: one of "
                             + ", ".join(CONVENTIONS))

    @property
    def label(self) -> str:
        """Short, for progress lines and messages: ``Phi=0.2 Ep/El=10 Es=Ep``."""
        return (f"Phi={self.surface_fraction:g} Ep/El={self.ratio:g} "
                + self.substrate.replace(" ", "").replace("_", "")
                + ("" if self.zeta_um == ZETA_UM else f" zeta={self.zeta_um:g}um"))

    @property
    def title(self) -> str:
        """For tables and figures: ``Phi = 0.2, E_p/E_l = 10, E_s = E_p``."""
        return (f"Phi = {self.surface_fraction:g}, E_p/E_l = {self.ratio:g}, {self.substrate}"
                + ("" if self.zeta_um == ZETA_UM else f", zeta = {self.zeta_um:g} um"))

    @property
    def substrate_E_Pa(self) -> float:
        return E_LENS if self.substrate == LENS else E_LENS * self.ratio

    def scene(self) -> Scene:
        """Table 1 (paper-fig3-sparse) with this Phi, E_p, substrate and zeta."""
        return load_scene("paper-fig3-sparse", [
            f"pillars.surface_fraction={self.surface_fraction!r}",
            f"pillars.E_Pa={E_LENS * self.ratio!r}", f"substrate.E_Pa={self.substrate_E_Pa!r}",
            "substrate.nu=0.5", f"load.indentation_um={self.zeta_um!r}"])


def grid(phis=PHIS, ratios=RATIOS, substrate: str = LENS,
         zeta_um: float = ZETA_UM) -> list[LatticePoint]:
    return [LatticePoint(p, r, substrate, zeta_um) for p in phis for r in ratios]


def paper_points(pairs=None, phis=PHIS, ratios=RATIOS,
                 zeta_um: float = ZETA_UM) -> list[LatticePoint]:
    """The E_s = E_p scenes: ``pairs`` of (Phi, E_p/E_l), by default those of
    :data:`PAPER_SCENES` whose Phi and ratio are in ``phis`` and ``ratios``."""
    if pairs is None:
        pairs = [(p, r) for p, r in PAPER_SCENES if p in phis and r in ratios]
    return [LatticePoint(p, r, PILLAR, zeta_um) for p, r in pairs]


def default_points(phis=PHIS, ratios=RATIOS, pairs=None,
                   zeta_um: float = ZETA_UM) -> list[LatticePoint]:
    """The study's scenes: the E_s = E_l grid, then the E_s = E_p scenes."""
    return grid(phis, ratios, LENS, zeta_um) + paper_points(pairs, phis, ratios, zeta_um)


def cases(point: LatticePoint, fem_levels=FEM_LEVELS, bem_levels=BEM_LEVELS,
          dense_levels=DENSE_LEVELS, fft_rungs=FFT_RUNGS) -> list[Case]:
    """fem-3d's levels, the Hooke BEM's, the elastic BEM's (same cells per diameter), the
    dense elastic BEM's, then the elastic bem-fft's single rungs."""
    scene = point.scene()
    out = [Case(FEM_MODEL, scene, {"mesh_size": float(s)}, tag=f"{point.label} fem")
           for s in fem_levels]
    for kind in (HOOKE, ELASTIC):
        out += [Case(BEM_MODEL, scene, {"cells_per_diameter": int(n), **BEM_OPTIONS[kind]},
                     tag=f"{point.label} {kind}") for n in bem_levels]
    out += [Case(DENSE_MODEL, scene, {"elements_per_diameter": int(n), **DENSE_OPTIONS},
                 tag=f"{point.label} dense {ELASTIC}") for n in dense_levels]
    out += [Case(BEM_MODEL, scene, {"cells_per_diameter": int(n), **BEM_OPTIONS[ELASTIC]},
                 tag=f"{point.label} {ELASTIC} rung") for n in fft_rungs]
    return out
