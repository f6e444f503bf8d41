"""The resolutions and methods the boundary-element models accept.

The solvers refuse a value outside these (``_dense._check_options``, ``_fft_grid.cell_size``);
the toolkit's option ranges (:mod:`validation.registry`) read them here, so an option is
refused before any solve with the name the user wrote.
"""

# P, square elements across a pillar diameter (dense BEM, and both levels of its
# Richardson-extrapolated variant): below 2 there is no element inside the disk; above 400 a
# single pillar top alone has 1.3e5 elements, beyond the dense operator's reach.
ELEMENTS_PER_DIAMETER_RANGE = (2, 400)
# N, grid cells across a pillar diameter (FFT BEM); the grid's own size caps it from above.
MIN_CELLS_PER_DIAMETER = 2
# The dense BEM's contact solvers: exact complementarity, or the paper's radius search.
CONTACT_METHODS = ("exact", "paper")
# The pillar of both BEMs: the paper's Hooke spring (uniform shortening, the default) or the
# elastic pillar's excess compliance from the Fourier-mode FEM (bem_solver._elastic_pillar).
PILLAR_MODELS = ("hooke", "elastic")
# Where the FFT model runs: numpy on the CPU, cupy on a CUDA GPU, or the GPU where there is one.
DEVICES = ("cpu", "gpu", "auto")
# The FFT model's arithmetic: float32 FFTs in the CG's steps with float64 gap refreshes (the
# default), or float64 throughout (bem_solver._fft_operator.CompliancePlan).
PRECISIONS = ("mixed", "double")
