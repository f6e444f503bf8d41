"""Scenes: the problem a model solves.

Units: SI inside the code (m, Pa, N).  Scene files state their units in the key names
(``radius_mm``, ``diameter_um``, ``E_Pa``); see :mod:`scenes._io`.
"""

from . import analytic, lattice
from ._io import apply_overrides, load_scene, preset_names, scene_dict, scene_from_dict, scene_to_toml
from ._scene import PHI_CLOSE_PACKING, Lens, Material, Pillars, Scene, SceneError
from .result import ContactResult, PillarForce, atomic_path, write_atomic

__all__ = [
    "PHI_CLOSE_PACKING",
    "ContactResult",
    "Lens",
    "Material",
    "PillarForce",
    "Pillars",
    "Scene",
    "SceneError",
    "analytic",
    "apply_overrides",
    "atomic_path",
    "lattice",
    "load_scene",
    "preset_names",
    "scene_dict",
    "scene_from_dict",
    "scene_to_toml",
    "write_atomic",
]
