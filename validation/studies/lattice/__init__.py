"""The multi-pillar cross-validation: the paper's Hooke BEM and the elastic-pillar BEM against
the 3D FEM.

Over surface fractions Phi and stiffness ratios E_p/E_l at zeta = 0.3 um (Table 1 otherwise),
two boundary-element models are compared with fem-3d (every pillar a fully elastic body bonded
to the substrate): the Hooke-spring BEM (``bem-fft``, every pillar a uniformly shortening
spring on a half-space, the paper's model) and the elastic-pillar BEM (``bem-fft`` with
``pillars = "elastic"``: each pillar's top compliance from an axisymmetric FEM, PHYSICS.md "The
elastic-pillar BEM").  Each model climbs its own refinement ladder (both BEMs the same
cells-per-diameter ladder); each quantity gets its Richardson estimate and GCI band
(validation.analysis.verification), and every BEM-FEM difference is set beside both models'
numerical uncertainty: a difference larger than the two bands together is a modelling error
of that BEM's pillar, not noise.

Substrate conventions.  The grid (Phi x E_p/E_l, :data:`PHIS` x :data:`RATIOS`) keeps the
substrate the lens material (E_s = E_l): it asks what the spring model costs when only the
pillars change, so the half-space compliance gamma_l + gamma_s is the same in every scene and
the comparison isolates the pillar.  :data:`PAPER_SCENES` adds scenes at the paper's
convention E_s = E_p (Table 1), where a soft or stiff pillar sits on a substrate of its own
material; every row, label, title and legend names its convention.

Targets of the elastic BEM (:data:`TARGETS`), each against fem-3d's Richardson estimate and
met when |(BEM - FEM) / FEM| is within the target or within both GCI bands where the bands
are wider (:func:`judge`): F_T within 1 %, sigma0 within 3 %, every ring's force within 2 %
(the ring forces are extrapolated like the other quantities) and the centre pillar's top
pressure along theta = 0 within 5 % at r = x d/2, x in :data:`PROFILE_POINTS` (r < 0.9 d/2:
the edge of a stiff pillar is singular).  Each row carries ``targets`` and the report
``targets_met`` (n of m scenes meet every target).

Per-pillar forces are also compared at the finest level of each model, grouped by lattice ring
(ring 0 is the centre pillar): the FEM/BEM ratio of every pillar both models load, its mean
and range per ring, and its change from the next-coarser pair of levels (a measure of how
settled the ratio is).

A row of ``lattice.json``: ``label``, ``title``, ``surface_fraction``, ``ratio`` (E_p/E_l),
``substrate`` (the convention) and ``substrate_E_Pa``; ``quantities`` (the Hooke BEM against
the FEM, per quantity ``fem``, ``fem_band``, ``bem``, ``bem_band``, ``difference`` = (FEM - BEM)
/ BEM, ``band`` = both bands over BEM, ``significant``) and ``elastic_quantities`` (the same
for the elastic BEM); ``rings`` and ``elastic_rings`` (finest-level force ratios by ring);
``ring_forces`` and ``profile`` (the Richardson estimates the ring and profile targets judge);
``targets``; each model's ``*_levels`` (the elastic bem-fft's single rungs in
``elastic_fft_rungs``); ``status``.

All cases run on the engine, so the study resumes after an interruption.

Modules: :mod:`.points` (the grid's constants, the lattice point, its cases),
:mod:`.analysis` (ladders, rings, profiles, targets: one row a point), :mod:`.run` (the study
on the engine), :mod:`.tables` (terminal text, CSV), :mod:`.plots` (figures) and
:mod:`.report` (the report folder).
"""

from ..targets import TARGETS, judge
from .analysis import compare_point, evaluate_targets, ring_ratios, targets_met
from .points import (BEM_LEVELS, BEM_MODEL, BEM_NAMES, BEM_OPTIONS, CONVENTIONS, DENSE_LEVELS,
                     DENSE_MODEL, DENSE_OPTIONS, E_LENS, ELASTIC, FEM_LEVELS, FEM_MODEL,
                     FFT_RUNGS, HOOKE, LENS, PAPER_SCENES, PHIS, PILLAR, PROFILE_POINTS,
                     QUICK_BEM_LEVELS, QUICK_DENSE_LEVELS, QUICK_FEM_LEVELS, QUICK_FFT_RUNGS,
                     RATIOS, ZETA_UM, LatticePoint, cases, default_points, grid, paper_points)
from .report import OUTPUTS, summary_markdown, write_report
from .run import lattice_study
from .tables import profile_csv, rings_csv, rows_csv, table_text, targets_table

__all__ = ["BEM_LEVELS", "BEM_MODEL", "BEM_NAMES", "BEM_OPTIONS", "CONVENTIONS", "DENSE_LEVELS",
           "DENSE_MODEL", "DENSE_OPTIONS", "ELASTIC", "E_LENS", "FEM_LEVELS", "FEM_MODEL",
           "FFT_RUNGS", "HOOKE", "LENS", "OUTPUTS", "PAPER_SCENES", "PHIS", "PILLAR",
           "PROFILE_POINTS", "QUICK_BEM_LEVELS", "QUICK_DENSE_LEVELS", "QUICK_FEM_LEVELS",
           "QUICK_FFT_RUNGS", "RATIOS", "TARGETS", "ZETA_UM", "LatticePoint", "cases",
           "compare_point", "default_points", "evaluate_targets", "grid", "judge",
           "lattice_study", "paper_points", "profile_csv", "ring_ratios", "rings_csv",
           "rows_csv", "summary_markdown", "table_text", "targets_met", "targets_table",
           "write_report"]
