"""Half-space (boundary-element) models of the lens-on-pillars contact.

Units: SI (m, Pa, N).  ``solve_dense`` is the paper's superposition method with an exact
complementarity solver (:mod:`bem_solver._dense`); ``solve_fft`` the matrix-free model on a
regular grid with FFT-applied kernel and constrained conjugate gradients
(:mod:`bem_solver._fft`), on the CPU or a CUDA GPU (``available_devices()``).  Both take
``pillars="hooke"`` (the paper's spring, default) or ``"elastic"`` (the pillar's excess
compliance from a Fourier-mode FEM, :mod:`bem_solver._elastic_pillar`).

The names below are imported on first use (PEP 562), so that reading a constant such as
:mod:`bem_solver._limits` (the CLI's option ranges) does not import scipy's solvers: the
CLI then starts in a fraction of a second.
"""

import importlib

# Each public name and the private module that defines it.
_EXPORTS = {
    "available_devices": "._xp",
    "cell_pattern": "._cells",
    "discretise": "._discretise",
    "disk_rectangle_area": "._disk",
    "disk_rectangle_centroid": "._disk",
    "estimate_memory": "._dense",
    "expansion": "._operator",
    "full_operator": "._operator",
    "lens_gap": "._dense",
    "love_rectangle": "._love",
    "love_square": "._love",
    "overlap_radius": "._discretise",
    "reduced_operator": "._operator",
    "solve_dense": "._dense",
    "solve_fft": "._fft",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name], __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__():
    return sorted([*globals(), *_EXPORTS])
