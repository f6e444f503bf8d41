"""Registry of the models a command can run, by the name given to ``--model``.

Each entry maps a model name to ``(module, function, options)``: ``function(scene, **options)``
returns a :class:`scenes.ContactResult`; ``options`` names the CLI options (attributes of the
parsed arguments) the model accepts.  Modules are imported on first use, so a command that
runs only the BEM never imports scikit-fem or gmsh.
"""

from __future__ import annotations

import importlib

from scenes import ContactResult, Scene

MODELS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "bem": ("bem_solver", "solve_dense", ("elements_per_diameter", "contact", "cells")),
    "fem-axisym": ("fem_reference", "solve_axisymmetric", ("mesh_size", "vtu_path")),
    "bem-fft": ("bem_solver._fft", "solve_fft", ("cells_per_diameter", "device",
                                                   "max_iterations")),
    "fem-3d": ("fem_reference", "solve_fem3d", ("mesh_size", "vtu_path")),
    "bem-richardson": ("bem_solver._extrapolated", "solve_dense_extrapolated",
                       ("elements_per_diameter", "cells")),
    # Closed forms as models (the planner's cheapest candidates).
    "hertz": ("scenes.closed_form_models", "solve_hertz", ()),
    "spring": ("scenes.closed_form_models", "solve_spring", ()),
    # The planner's choice for this scene (default tolerance and quantities); the plan is
    # recorded in the result's diagnostics["plan"].
    "auto": ("validation.planner.plan", "solve_auto", ("tolerance", "quantities", "budget")),
}


def model_names() -> list[str]:
    return sorted(MODELS)


def run_model(name: str, scene: Scene, **options) -> ContactResult:
    """Run model ``name`` on ``scene``; options that are None are left to the model's default."""
    if name not in MODELS:
        raise ValueError(f"--model {name!r}: unknown; available: {', '.join(model_names())}")
    module, function, accepted = MODELS[name]
    solver = getattr(importlib.import_module(module), function)
    kwargs = {k: v for k, v in options.items() if k in accepted and v is not None}
    return solver(scene, **kwargs)
