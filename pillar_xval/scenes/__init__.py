"""Scenes: the problem a model solves.

Units: SI inside the code (m, Pa, N).  Scene files state their units in the key names
(``radius_mm``, ``diameter_um``, ``E_Pa``); see :mod:`pillar_xval.scenes._io` (files and presets),
:mod:`pillar_xval.scenes._overrides` (``--set``), :mod:`pillar_xval.scenes._checks` (allowed ranges) and
:mod:`pillar_xval.scenes._tables` (file table to Scene, errors in file keys and units).
"""

from . import analytic, floor, lattice
from ._checks import LENGTH_RANGE_M, MODULUS_RANGE_PA, PHI_CLOSE_PACKING, POISSON_RANGE
from ._io import load_scene, preset_names, scene_dict, scene_loader, scene_to_toml
from ._overrides import apply_overrides
from ._tables import scene_from_dict
from ._errors import InputError, SceneError, ScopeError, ToolError
from ._scene import Lens, Material, Pillars, Scene

__all__ = [
    "LENGTH_RANGE_M",
    "MODULUS_RANGE_PA",
    "PHI_CLOSE_PACKING",
    "POISSON_RANGE",
    "InputError",
    "Lens",
    "Material",
    "Pillars",
    "Scene",
    "SceneError",
    "ScopeError",
    "ToolError",
    "analytic",
    "apply_overrides",
    "floor",
    "lattice",
    "load_scene",
    "preset_names",
    "scene_dict",
    "scene_from_dict",
    "scene_loader",
    "scene_to_toml",
]
