"""The scenes behind the paper's Figs. 3-8, as sweeps on the engine.

Every scene is the paper's Table 1 (``paper-fig3-sparse``: R = 2 mm, d = 4 um, h = 2 um,
E_l = 1.6 MPa, every nu = 0.5) with the paper's convention E_s = E_p, varied along:

- ``fig3``: Phi = 0.03 and 0.82 at zeta = 0.3 um, E_p = E_l (pressure maps kept);
- ``fig4a``: sigma_0(Phi) at zeta = 0.3 um for E_p/E_l = 1e-3 ... 1e6, one per decade;
- ``fig4b``: A against pi a^2 at E_p = E_l, a few Phi, zeta over Table 1's 0.005-0.5 um;
- ``fig5``: the single pillar (Phi = 2.3e-3, zeta = 0.3 um) for E_p over Table 1's 1e3-1e12 Pa;
- ``master`` (Figs. 6-8): Phi x zeta = 0.05 ... 0.5 um x E_p/E_l = 1e-3, 1, 1e6.

:class:`FigureGrid` holds the values (``full()`` for the paper, ``quick()`` for tests);
:func:`figure_sweeps` turns them into :class:`~validation.studies.sweep.Sweep` objects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pillar_xval.scenes import load_scene

from ..sweep import ModelSpec, Sweep, crossed, log, zipped

BASE_SCENE = "paper-fig3-sparse"
LENS_E_PA = 1.6e6
# Fig. 3's scenes (paper, Fig. 3a and 3b).
FIG3_PHIS = (0.03, 0.82)
FIG3_ZETA_UM = 0.3
# Fig. 5: the paper's single-pillar surface fraction.
FIG5_PHI = 2.3e-3


def _clean(x: float) -> float:
    """``x`` to 6 significant digits: 1.6e6 * 1e-3 reads 1600, not 1600.0000000000002."""
    return float(f"{x:.6g}")


@dataclass(frozen=True)
class FigureGrid:
    """The values swept for each figure (file units: um, Pa; ratios are E_p/E_l).

    ``elements_per_diameter`` is the model's resolution for Figs. 4-8; Fig. 3's two maps are
    drawn one level up (``map_elements_per_diameter``), and its dense scene is also solved with
    the paper's contact-radius search and the exact solver at ``search_elements_per_diameter``
    (dense BEM), side by side.  ``threshold_*`` set the bisection of
    the single-pillar threshold (dense BEM at that P, that many halvings of the bracket in log
    Phi) and the indentations it runs at besides the master grid's.
    """

    phis: tuple
    zetas_um: tuple
    ratios: tuple
    fig4a_ratios: tuple
    fig4b_phis: tuple
    fig4b_zetas_um: tuple
    fig5_E_Pa: tuple
    elements_per_diameter: int
    map_elements_per_diameter: int
    threshold_elements_per_diameter: int
    threshold_steps: int
    search_elements_per_diameter: int
    map_pixels: int = 520
    dpi: int = 120
    threshold_extra_zetas_um: tuple = ()
    name: str = "full"
    notes: dict = field(default_factory=dict)

    @classmethod
    def full(cls, elements_per_diameter: int = 5) -> "FigureGrid":
        """The paper's ranges (Table 1), dense enough for smooth curves and fits."""
        return cls(
            phis=tuple(_clean(x) for x in log(2.3e-3, 0.82, 20)),
            zetas_um=tuple(_clean(0.05 * k) for k in range(1, 11)),
            ratios=(1e-3, 1.0, 1e6),
            fig4a_ratios=tuple(10.0**k for k in range(-3, 7)),
            fig4b_phis=(2.3e-3, 0.01, 0.03, 0.1, 0.2, 0.4, 0.82),
            fig4b_zetas_um=tuple(_clean(x) for x in log(0.005, 0.5, 11)),
            fig5_E_Pa=tuple(_clean(10.0 ** (3 + k / 2)) for k in range(19)),
            elements_per_diameter=elements_per_diameter,
            map_elements_per_diameter=2 * elements_per_diameter - 1,
            threshold_elements_per_diameter=21,
            threshold_steps=7,
            search_elements_per_diameter=11,
            threshold_extra_zetas_um=(0.005, 0.01, 0.02, 0.03),
            name="full")

    @classmethod
    def quick(cls, elements_per_diameter: int = 5) -> "FigureGrid":
        """A coarse version of every figure, for tests (a few seconds)."""
        return cls(
            phis=(2.3e-3, 0.01, 0.03, 0.1, 0.3, 0.82),
            zetas_um=(0.1, 0.3),
            ratios=(1e-3, 1.0, 1e6),
            fig4a_ratios=(1e-3, 1.0, 1e6),
            fig4b_phis=(0.03, 0.3),
            fig4b_zetas_um=(0.02, 0.1, 0.3),
            fig5_E_Pa=(1e3, 1.6e6, 1e12),
            elements_per_diameter=elements_per_diameter,
            map_elements_per_diameter=elements_per_diameter,
            threshold_elements_per_diameter=7,
            threshold_steps=3,
            search_elements_per_diameter=5,
            map_pixels=240,
            dpi=60,
            threshold_extra_zetas_um=(),
            name="quick")

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


def material_sets(ratio: float) -> dict:
    """Overrides giving E_p = E_s = ratio * E_l (the paper's E_s = E_p), in Pa."""
    e = _clean(ratio * LENS_E_PA)
    return {"pillars.E_Pa": e, "substrate.E_Pa": e}


def _ratio_axis(ratios) -> object:
    sets = [material_sets(r) for r in ratios]
    return zipped({k: [s[k] for s in sets] for k in ("pillars.E_Pa", "substrate.E_Pa")})


def figure_sweeps(grid: FigureGrid, model: str, options: dict) -> dict[str, Sweep]:
    """One sweep per figure (``fig3`` ... ``fig5``, ``master``) with ``model(options)``;
    ``options`` is the model's options for Figs. 4-8 (Fig. 3 is drawn at
    ``grid.map_elements_per_diameter``)."""
    spec = (ModelSpec(model, dict(options)),)
    map_spec = (ModelSpec(model, {**options,
                                  "elements_per_diameter": grid.map_elements_per_diameter}),)
    phi, zeta = "pillars.surface_fraction", "load.indentation_um"
    return {
        "fig3": Sweep(BASE_SCENE, (crossed(phi, FIG3_PHIS), crossed(zeta, [FIG3_ZETA_UM]),
                                   _ratio_axis([1.0])), map_spec, name="fig3"),
        "fig4a": Sweep(BASE_SCENE, (_ratio_axis(grid.fig4a_ratios), crossed(phi, grid.phis),
                                    crossed(zeta, [FIG3_ZETA_UM])), spec, name="fig4a"),
        "fig4b": Sweep(BASE_SCENE, (crossed(phi, grid.fig4b_phis),
                                    crossed(zeta, grid.fig4b_zetas_um), _ratio_axis([1.0])),
                       spec, name="fig4b"),
        "fig5": Sweep(BASE_SCENE, (crossed(phi, [FIG5_PHI]), crossed(zeta, [FIG3_ZETA_UM]),
                                   zipped({"pillars.E_Pa": list(grid.fig5_E_Pa),
                                           "substrate.E_Pa": list(grid.fig5_E_Pa)})),
                      spec, name="fig5"),
        "master": Sweep(BASE_SCENE, (_ratio_axis(grid.ratios), crossed(zeta, grid.zetas_um),
                                     crossed(phi, grid.phis)), spec, name="master"),
    }


def expected_pillars(scene) -> float:
    """Rough pillars in contact, Phi times the area 2 pi R zeta over a pillar top: orders the
    cases so that the longest start first (the pool then ends evenly)."""
    p = scene.pillars
    area = 2.0 * math.pi * scene.lens.radius_m * scene.indentation_m
    return max(1.0, p.surface_fraction * area / (math.pi * p.diameter_m**2 / 4.0))


def table1_scene(phi: float, zeta_um: float, ratio: float):
    """The Table 1 scene at (Phi, zeta, E_p/E_l), E_s = E_p."""
    sets = [f"pillars.surface_fraction={phi!r}", f"load.indentation_um={zeta_um!r}",
            *(f"{k}={v!r}" for k, v in material_sets(ratio).items())]
    return load_scene(BASE_SCENE, sets)


def pillar_height() -> float:
    """h of Table 1 (m), the unit of the reduced indentation zeta/h."""
    return table1_scene(0.01, FIG3_ZETA_UM, 1.0).pillars.height_m


def in_um(length_m: float) -> float:
    """A length in um, rounded so that equal grid values compare equal."""
    return round(length_m * 1e6, 9)
