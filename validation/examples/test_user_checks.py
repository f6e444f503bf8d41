"""Tolerance checks as a user writes them in their own repository (``pytest`` runs this file
as it is once pillar-xval is installed: the ``xval`` fixture comes with the toolkit).

Each check states its tolerance and where that tolerance comes from.  The first run solves
the cases (a few seconds); a rerun reads them from pytest's cache and solves nothing.
"""

from validation.testing import assert_close, assert_converged, assert_matches_closed_form

# Tolerances named by their source (measured on this toolkit's own verification).
RTOL_HERTZ_BEM = 0.02   # dense BEM at P = 9 on the Hertz scene: measured within 1 %
RTOL_BEM_FEM = 0.03     # dense BEM (P = 11) against fem-axisym, rigid punch: measured 2.2 %


def test_dense_bem_reaches_hertz(xval):
    scene = xval.scene("hertz")
    bem = xval.run("bem", scene, elements_per_diameter=9)
    assert_converged(bem)
    assert_matches_closed_form(bem, "hertz", rtol=RTOL_HERTZ_BEM, quantities=("F_T",),
                               source="dense BEM at P = 9, measured within 1 %")


def test_bem_against_fem_on_one_pillar(xval):
    scene = xval.scene("single-pillar", "pillars.rigid=true", "substrate.rigid=true")
    bem = xval.run("bem", scene, elements_per_diameter=11)
    fem = xval.run("fem-axisym", scene, mesh_size=2.0)
    assert_close(bem, fem, ("F_T",), rtol=RTOL_BEM_FEM,
                 source="dense BEM P = 11 against fem-axisym, measured 2.2 %")
