"""Half-space (boundary-element) models of the lens-on-pillars contact.

Units: SI (m, Pa, N).  ``solve_dense`` is the paper's superposition method with an exact
complementarity solver (:mod:`bem_solver._dense`); ``solve_fft`` the matrix-free model on a
regular grid with FFT-applied kernel and constrained conjugate gradients
(:mod:`bem_solver._fft`), on the CPU or a CUDA GPU (``available_devices()``).
"""

from ._cells import cell_pattern
from ._disk import disk_rectangle_area, disk_rectangle_centroid
from ._dense import estimate_memory, lens_gap, solve_dense
from ._discretise import discretise, overlap_radius
from ._fft import solve_fft
from ._love import love_rectangle, love_square
from ._operator import expansion, full_operator, reduced_operator
from ._xp import available_devices

__all__ = [
    "available_devices",
    "cell_pattern",
    "discretise",
    "disk_rectangle_area",
    "disk_rectangle_centroid",
    "estimate_memory",
    "expansion",
    "full_operator",
    "lens_gap",
    "love_rectangle",
    "love_square",
    "overlap_radius",
    "reduced_operator",
    "solve_dense",
    "solve_fft",
]
