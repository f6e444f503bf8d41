"""The models, one declaration each (:class:`~.model.Model`): the only place a model is
described.  Every command, study, the engine and the planner read these; a new model is a new
declaration here and its solver, nothing else (ARCHITECTURE.md, "A new model")."""

from __future__ import annotations

from .ladders import Ladder
from .model import CostLaw, Model
from .options import (CELLS, CELLS_PER_DIAMETER, CONTACT, DEVICE, ELEMENTS_PER_DIAMETER,
                      MAX_ITERATIONS, MESH_SIZE, MESH_SIZE_3D, PILLARS, PLANNED, PRECISION)

__all__ = ["DECLARED"]

# A closed form's time does not grow with anything: one constant term (numpy's own work on
# one thread, as the reference assembly).
_NO_COST = CostLaw("none", None, (0,))

# Every model below solves a force-controlled scene itself (force_control = "native"): the
# BEMs' and FEMs' contact solvers take the force as a constraint, the closed forms invert
# exactly, auto plans at the estimated indentation (how: each solver's module docstring).
DECLARED = (
    Model(
        "bem", "bem_solver:solve_dense",
        "dense boundary-element model: Love elements, Hooke or elastic pillars, exact "
        "complementarity",
        options={"elements_per_diameter": ELEMENTS_PER_DIAMETER, "cells": CELLS,
                 "contact": CONTACT, "pillars": PILLARS},
        # Square elements across a pillar (or Hertz contact) diameter, 11, 23, 47, ...;
        # 'covered' cells carry the true disk area, so the sequence converges smoothly.
        ladder=Ladder("elements_per_diameter", 11, 2.0, "odd", -1.0, (5, 7, 9, 11, 15, 21),
                      {"cells": "covered"}, "element side / diameter = 1/P"),
        physics="hooke-pillar",
        # Uniform-pressure elements give O(h) at the pillar edges (measured 1.0-1.05 on
        # paper-fig3-dense).
        expected_order=1.0,
        scopes=("flat", "single", "multi"),
        # Start-up, then assembly and dense factorisation; its time follows the reference
        # assembly (numpy's vectorised coefficient work).
        cost=CostLaw("dense-unknowns", "log_unknowns", (0, 2, 3), {"kind": "estimate"},
                     (("assembly", 1.0),)),
        reference_rungs={"multi": (11, 15, 21), "flat": (11, 15, 21)},
        robustness={"elements_per_diameter": 7}, keeps_fields=True,
        force_control="native"),
    Model(
        "bem-richardson", "bem_solver._extrapolated:solve_dense_extrapolated",
        "the dense BEM at P and 2P - 1, Richardson-extrapolated",
        options={"elements_per_diameter": ELEMENTS_PER_DIAMETER, "cells": CELLS,
                 "pillars": PILLARS},
        # Coarse levels 5, 11, 23, ...
        ladder=Ladder("elements_per_diameter", 5, 2.0, "odd", -1.0, (5, 7, 9, 11),
                      {"cells": "covered"},
                      "coarse element side / diameter = 1/P (fine level 2P - 1)"),
        physics="hooke-pillar",
        force_control="native"),
    Model(
        "bem-fft", "bem_solver._fft:solve_fft",
        "FFT boundary-element model: regular grid, constrained CG, numpy or cupy",
        options={"cells_per_diameter": CELLS_PER_DIAMETER, "device": DEVICE,
                 "max_iterations": MAX_ITERATIONS, "pillars": PILLARS,
                 "precision": PRECISION},
        # Grid cells across a pillar diameter, 32, 64, 128, ...
        # N = 28 between 24 and 32 keeps adjacent rungs under 2x apart in time (24 -> 32 took
        # 1.5-2.6x), so a plan one rung finer than needed stays within 2x of the cheapest.
        ladder=Ladder("cells_per_diameter", 32, 2.0, "int", -1.0,
                      (8, 12, 16, 24, 28, 32, 48, 64), {}, "cell side / diameter = 1/N"),
        physics="hooke-pillar", expected_order=1.0,
        scopes=("flat", "single", "multi"),
        # FFTs per iteration times iterations that grow about as sqrt(n).  Its time follows
        # the reference FFT pair for a fifth and numpy's one-thread work for the rest: on 16
        # cores a 1e6-cell solve ran 1.23x faster on 16 threads than on 1 (Amdahl's
        # threaded share 0.2) and the calibration's small cases no faster; with the FFT
        # alone the planner's predictions at 16 threads fell 1.8 rms short of the solves.
        cost=CostLaw("fft-grid", "log_points", (0, 1, 1.5), None,
                     (("fft", 0.2), ("assembly", 0.8))),
        reference_rungs={"multi": (32, 48, 64), "flat": (32, 48, 64)},
        # 3000 CG iterations in extremes: the default, 20 sqrt(cells) + 500, reaches 14000 on
        # the widest corners, an hour of a stagnating solve where a verdict is wanted.
        robustness={"cells_per_diameter": 16, "max_iterations": 3000}, keeps_fields=True,
        force_control="native", floor=True),
    Model(
        "fem-axisym", "fem_reference.axisym:solve",
        "axisymmetric FEM with one elastic pillar (scikit-fem, Taylor-Hood P2/P1)",
        options={"mesh_size": MESH_SIZE},
        # The mesh builder's single size parameter scales every element size.
        ladder=Ladder("mesh_size", 1.0, 0.5, "float", 1.0, (4.0, 2.0, 1.0, 0.5), {},
                      "mesh_size (relative)"),
        physics="elastic-pillar",
        scopes=("flat", "single"), scope_note="refuses scenes where a second pillar touches "
                                                "(fem-3d holds them)",
        # A sparse LU (SuperLU, one thread) after scikit-fem's assembly: the reference
        # assembly's machine.
        cost=CostLaw("fem-dofs", "log_dofs", (0, 1, 1.5), {"kind": "estimate"},
                     (("assembly", 1.0),)),
        reference_rungs={"single": (2.0, 1.0, 0.5), "flat": (2.0, 1.0, 0.5)},
        # The fast subset of extremes meshes it coarser: it checks robustness, not accuracy.
        robustness={"mesh_size": 2.0}, robustness_quick={"mesh_size": 4.0},
        keeps_fields=True, weak_contact=True,
        force_control="native", floor=True, reference_for=("single-pillar",)),
    Model(
        "fem-3d", "fem_reference.solid3d:solve",
        "3D FEM of the lattice's pi/6 wedge with elastic pillars (PARDISO, constrained CG)",
        options={"mesh_size": MESH_SIZE_3D},
        # Ratio sqrt(2) per level (each halving of the size multiplies the unknowns by ~8);
        # 2.83, 2, 1.41 fit this machine on the paper's densest scene (validation/bench/fem3d.py).
        ladder=Ladder("mesh_size", 2 * 2**0.5, 2 ** -0.5, "float", 1.0,
                      (4.0, 2.83, 2.0, 1.41), {}, "mesh_size (relative)"),
        physics="elastic-pillar",
        robustness={"mesh_size": 4.0}, weak_contact=True,
        # Its rungs take minutes each (validation/bench/fem3d.py).
        expensive=True,
        force_control="native", floor=True, reference_for=("lattice",)),
    # Closed forms as models: the planner's cheapest candidates.
    Model(
        "hertz", "pillar_xval.closed_forms:solve_hertz",
        "Hertz on the substrate (flat), or the Hertz-like limit of a dense lattice",
        scopes=("flat", "multi"), scope_note="one pillar touches: no continuum",
        cost=_NO_COST, robustness={},
        force_control="native"),
    Model(
        "spring", "pillar_xval.closed_forms:solve_spring",
        "the paper's soft-flat-punch (spring) model of one pillar",
        scopes=("single",), scope_note="a second pillar touches, or the scene is flat",
        cost=_NO_COST, robustness={},
        force_control="native"),
    # The planner's choice for the scene (default tolerance and quantities); the plan is
    # recorded in the result's diagnostics["plan"].
    Model(
        "auto", "validation.planner.plan:solve_auto",
        "the planner's choice for the scene (pillar-xval plan)",
        options={"tolerance": PLANNED, "quantities": PLANNED, "budget": PLANNED},
        # The plan comes from the planner's code and its data (validation/planner/data).
        code=("validation.planner",), request="validation.planner.plan:check_request",
        force_control="native", floor=True),
)
