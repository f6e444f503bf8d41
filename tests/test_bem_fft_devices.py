"""The FFT model is written once against an array namespace: run it through a second, strict
namespace (array_api_strict, which refuses numpy-only idioms: ``out=`` arguments, ``.flat``,
float times bool, scatters by integer arrays, numpy functions on its arrays) and compare with
the numpy path; on a machine with a CUDA GPU, compare cupy with numpy too (marked ``gpu``).
"""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from pillar_xval.scenes import InputError, load_scene

from bem_solver import available_devices
import bem_solver._fft as fft_module
from bem_solver._fft import GPU_WARM_START_LEVELS, solve_fft
from bem_solver._fft_grid import build_grid
from bem_solver._fft_operator import CompliancePlan, near_field_correction
from bem_solver._xp import NumpyDevice, select_backend

# With the same FFT library, dot and sparse products both paths evaluate the same
# floating-point expressions: their differences are round-off, ~1e-15 relative, amplified by
# the constrained CG at most by its conditioning (~1e2); 1e-12 leaves a margin of 10.  One
# operator application through the standard's FFT (numpy.fft, not scipy.fft) differs by
# round-off too.  (A whole solve with another FFT or summation order drifts further: ~1e-11
# after 80 clipped CG iterations.)
RTOL_ROUNDOFF = 1e-12
# A GPU's FFT rounds differently; the constrained CG may then take another path to the same
# tolerance (1e-8 zeta in the gap), so forces agree to the solver tolerance times the
# conditioning of the contact problem (~1e2).
RTOL_SOLVER = 1e-6

xps = pytest.importorskip("array_api_strict")


class StrictSparse:
    """COO matrix whose product (by a vector or the columns of a 2-D array) is a segment sum
    (no numpy), or scipy's CSR product."""

    def __init__(self, backend, rows, cols, values, n, scipy_product=False, columns=None):
        self.be, self.rows, self.cols, self.values, self.n = backend, rows, cols, values, n
        self.nnz = int(rows.shape[0])
        self.csr = NumpyDevice().sparse(*(backend.to_numpy(a) for a in (rows, cols, values)),
                                        n, columns) if scipy_product else None

    def __matmul__(self, q):
        if self.csr is not None:
            return xps.asarray(self.csr @ self.be.to_numpy(q))
        if q.ndim == 2:
            return xps.stack([self @ q[:, k] for k in range(q.shape[1])], axis=1)
        return self.be.segment_sum(self.rows, self.values * xps.take(q, self.cols), self.n)

    def diagonal(self):
        return self.be.segment_sum(self.rows, xps.where(self.rows == self.cols, self.values,
                                                        0.0), self.n)

    def toarray(self):
        out = np.zeros((self.n, self.n))
        np.add.at(out, (self.be.to_numpy(self.rows), self.be.to_numpy(self.cols)),
                  self.be.to_numpy(self.values))
        return out


class StrictDevice:
    """array_api_strict arrays.  Only the backend primitives that the standard lacks (segment
    sums and scatters) pass through numpy, inside this class.  FFTs, dot and sparse products:
    the standard's (``xps.fft``, ``xps.vecdot``, a segment-sum product), or with
    ``numpy_primitives=True`` the numpy backend's own (scipy.fft, einsum, scipy.sparse), so
    that a whole solve differs from the numpy path only by what the generic code does."""

    name = "array_api_strict"
    device = "cpu"
    xp = xps
    max_fft_points = NumpyDevice().max_fft_points

    def __init__(self, numpy_primitives: bool = False):
        self.numpy_primitives = numpy_primitives
        if numpy_primitives:
            cpu = NumpyDevice()
            for name in ("rfft2", "irfft2", "rfft", "fft", "ifft", "irfft"):
                setattr(self, name, self._through(getattr(cpu, name)))
            self.dot = lambda a, b: cpu.dot(self.to_numpy(a), self.to_numpy(b))

    def _through(self, transform):
        return lambda a, *args, **kw: xps.asarray(transform(self.to_numpy(a), *args, **kw))

    def asarray(self, a, dtype=None):
        return xps.asarray(np.asarray(a) if isinstance(a, np.ndarray) else a, dtype=dtype)

    def to_numpy(self, a):
        return np.from_dlpack(a) if not isinstance(a, np.ndarray) else a

    def dot(self, a, b):
        return float(xps.vecdot(a, b))

    def segment_sum(self, index, weights, n):
        return xps.asarray(np.bincount(self.to_numpy(index), weights=self.to_numpy(weights),
                                       minlength=n))

    def segments(self, index, n):
        # a backend primitive, as segment_sum: numpy's, so both paths sum in the same order
        numpy_sums = NumpyDevice().segments(self.to_numpy(index), n)
        return lambda weights: xps.asarray(numpy_sums(self.to_numpy(weights)))

    def spreader(self, index):
        return lambda values, lo=0, hi=None: xps.take(values, index[lo:hi])

    def put(self, target, index, values):
        out = np.array(self.to_numpy(target))
        out[self.to_numpy(index)] = self.to_numpy(values)
        return xps.asarray(out)

    def rfft2(self, a):  # over the last two axes, as scipy's (a stack of boxes, or one)
        return xps.fft.fft(xps.fft.rfft(a, axis=-1), axis=-2)

    def irfft2(self, a, s):
        return xps.fft.irfft(xps.fft.ifft(a, axis=-2), n=s[-1], axis=-1)

    def rfft(self, a, axis):
        return xps.fft.rfft(a, axis=axis)

    def fft(self, a, n, axis):
        return xps.fft.fft(a, n=n, axis=axis)

    def ifft(self, a, axis):
        return xps.fft.ifft(a, axis=axis)

    def irfft(self, a, n, axis):
        return xps.fft.irfft(a, n=n, axis=axis)

    def next_fast_len(self, n):
        return NumpyDevice().next_fast_len(n)

    def sparse(self, rows, cols, values, n, columns=None):
        return StrictSparse(self, rows, cols, values, n, self.numpy_primitives, columns)

    def synchronize(self):
        pass


def _gpu_or_skip():
    reason = available_devices()["gpu"]
    if reason:
        pytest.skip(reason)


SCENES = [
    ("hertz", [], 12, {}),
    ("single-pillar", ["pillars.E_Pa=160"], 10, {}),
    ("paper-fig3-sparse", [], 16, {}),  # warm start from N = 8
    ("paper-fig3-dense", ["pillars.rigid=true"], 8, {}),
    ("paper-fig3-dense", [], 8, {"edge_correction": False}),
]


def _agree(a, b, rtol, zeta):
    assert b.iterations == a.iterations
    for field in ("total_force_N", "centre_pressure_Pa", "contact_radius_m",
                  "real_contact_area_m2"):
        assert getattr(b, field) == pytest.approx(getattr(a, field), rel=rtol), field
    pa, pb = a.fields["pressure_Pa"], b.fields["pressure_Pa"]
    assert np.max(np.abs(pb - pa)) <= rtol * np.max(np.abs(pa))
    assert np.max(np.abs(b.fields["gap_m"] - a.fields["gap_m"])) <= rtol * zeta


# The numpy path with its column transforms whole: the generic path's grid and operations,
# so the strict namespace's answer to round-off (the default splits them: the same operator
# to round-off, tested below and in test_bem_fft).
UNSPLIT = NumpyDevice(split_columns=False)


@pytest.mark.parametrize("case", SCENES, ids=lambda c: f"{c[0]}{c[1]}{c[3]}")
def test_split_column_transforms_give_the_whole_transforms_answer(case):
    """The numpy path's default operator (its column transforms split in halves on a grid
    of 2 M rows) against the whole transforms on the generic path's grid: the same solution
    within the solver's tolerance (RTOL_SOLVER; the float32 steps round differently, so the
    iterates differ by round-off that the CG's stopping test bounds: measured 4e-10 to 2.3e-9)."""
    name, overrides, n, options = case
    scene = load_scene(name, overrides)
    whole = solve_fft(scene, n, backend=UNSPLIT, **options)
    split = solve_fft(scene, n, **options)
    assert split.converged and whole.converged
    assert split.diagnostics["fft_shape"][0] % 2 == 0
    for field in ("total_force_N", "centre_pressure_Pa", "contact_radius_m"):
        assert getattr(split, field) == pytest.approx(getattr(whole, field), rel=RTOL_SOLVER)
    assert split.diagnostics["max_interpenetration_m"] <= 1e-8 * scene.indentation_m


@pytest.mark.parametrize("case", SCENES, ids=lambda c: f"{c[0]}{c[1]}{c[3]}")
def test_strict_namespace_gives_the_numpy_answer(case):
    name, overrides, n, options = case
    scene = load_scene(name, overrides)
    ref = solve_fft(scene, n, backend=UNSPLIT, **options)
    strict = solve_fft(scene, n, backend=StrictDevice(numpy_primitives=True), **options)
    assert ref.converged and strict.converged
    _agree(ref, strict, RTOL_ROUNDOFF, scene.indentation_m)
    assert strict.diagnostics["operator_applications"] == \
        ref.diagnostics["operator_applications"]


@pytest.mark.parametrize("case", [("paper-fig3-sparse", [], 16), ("hertz", [], 12)],
                         ids=lambda c: c[0])
def test_strict_namespace_under_a_force(case):
    """Force control (the constrained CG's approach as the multiplier, the grid's design
    rounds) uses the array API alone: the strict namespace gives the numpy answer."""
    name, overrides, n = case
    scene = load_scene(name, overrides)
    scene = scene.at_force(solve_fft(scene, n).total_force_N)
    ref = solve_fft(scene, n, backend=UNSPLIT)
    strict = solve_fft(scene, n, backend=StrictDevice(numpy_primitives=True))
    assert ref.converged and strict.converged
    assert strict.indentation_m == pytest.approx(ref.indentation_m, rel=RTOL_ROUNDOFF)
    _agree(ref, strict, RTOL_ROUNDOFF, ref.indentation_m)


def _plans(backend, scene_name, overrides, n):
    scene = load_scene(scene_name, overrides)
    grid = build_grid(scene, n)
    corr = near_field_correction(grid, scene.half_space_compliance, backend=backend)
    plan = CompliancePlan(grid.shape, grid.flat_index, grid.cell_size,
                          scene.half_space_compliance, pillar=grid.pillar,
                          spring_compliance=scene.pillar_spring_compliance,
                          correction=corr, backend=backend)
    return grid, plan


@pytest.mark.parametrize("backend", [StrictDevice, pytest.param("gpu", marks=pytest.mark.gpu)],
                         ids=["strict", "gpu"])
def test_operator_on_every_backend_equals_numpy(backend):
    """Kernel table, spectrum, near-field correction and Hooke term built on the device."""
    if backend == "gpu":
        _gpu_or_skip()
        backend = select_backend("gpu")
    else:
        backend = backend()
    case = ("paper-fig3-dense", ["load.indentation_um=0.05"], 9)
    grid, ref = _plans(NumpyDevice(), *case)
    _, dev = _plans(backend, *case)
    q = np.random.default_rng(11).random(grid.n_cells)
    u_ref = ref(q)
    u_dev = backend.to_numpy(dev(backend.asarray(q)))
    assert np.max(np.abs(u_dev - u_ref)) <= RTOL_ROUNDOFF * np.max(np.abs(u_ref))
    np.testing.assert_allclose(backend.to_numpy(dev.diagonal), ref.diagonal,
                               rtol=RTOL_ROUNDOFF)
    assert dev.correction.nnz == ref.correction.nnz


def test_device_selection():
    assert select_backend("cpu").device == "cpu"
    assert solve_fft(load_scene("hertz"), 8, device="cpu").diagnostics["device"] == "cpu"
    with pytest.raises(InputError, match="device"):
        select_backend("tpu")
    reason = available_devices()["gpu"]
    if reason:
        # One line saying what to install or what is missing; auto falls back to the CPU.
        with pytest.raises(InputError, match="gpu") as err:
            solve_fft(load_scene("hertz"), 8, device="gpu")
        assert "\n" not in str(err.value)
        assert select_backend("auto").device == "cpu"
    else:
        assert select_backend("auto").device == "gpu"


@pytest.mark.gpu
@pytest.mark.parametrize("case", SCENES[1:4], ids=lambda c: f"{c[0]}{c[1]}")
def test_gpu_gives_the_cpu_answer(case):
    _gpu_or_skip()
    name, overrides, n, options = case
    scene = load_scene(name, overrides)
    cpu = solve_fft(scene, n, **options)
    gpu = solve_fft(scene, n, device="gpu", **options)
    assert gpu.converged and gpu.diagnostics["device"] == "gpu"
    assert gpu.total_force_N == pytest.approx(cpu.total_force_N, rel=RTOL_SOLVER)
    assert gpu.centre_pressure_Pa == pytest.approx(cpu.centre_pressure_Pa, rel=RTOL_SOLVER)
    assert gpu.diagnostics["max_interpenetration_m"] <= 1e-8 * scene.indentation_m


def test_bench_gpu_runs_and_says_what_is_pending(tmp_path):
    """The GPU benchmark (validation/bench/gpu.py) on one tiny level: a table and a JSON file;
    without a GPU the GPU column is reported pending, with the reason."""
    import json

    from validation.bench import gpu as bench_gpu

    assert bench_gpu.main(["--out", str(tmp_path), "--levels", "8", "--repeats", "1",
                           "--pillars", "rigid"]) == 0
    doc = json.loads((tmp_path / "bench_gpu.json").read_text())
    (row,) = doc["rows"]
    assert row["cpu"]["converged"] and row["cpu"]["kernel_table_s"] > 0
    if doc["meta"]["gpu_pending"]:
        assert "gpu" not in row and "GPU column pending" in doc["table"]
    else:
        assert abs(row["force_rel_diff"]) <= RTOL_SOLVER
    # Solved twice in its interpreter: the repeat is the same solve (same grid, same start).
    assert row["cpu"]["again_wall_time_s"] > 0
    assert abs(row["cpu"]["again_force_rel_diff"]) <= RTOL_ROUNDOFF


def test_bench_gpu_past_its_budget_reports_every_case_skipped(tmp_path):
    """--budget-s 0 starts nothing: every case is in the file, each saying why it did not run
    (a lent machine's run that ends at its budget still writes what it skipped)."""
    import json

    from validation.bench import gpu as bench_gpu

    assert bench_gpu.main(["--out", str(tmp_path), "--levels", "8", "16", "--repeats", "1",
                           "--budget-s", "0"]) == 0
    doc = json.loads((tmp_path / "bench_gpu.json").read_text())
    assert len(doc["rows"]) == 4
    for row in doc["rows"]:
        assert "past --budget-s 0" in row["cpu"]["error"]
    assert doc["table"].count("past --budget-s 0") >= 4


class _NumpyStandIn(types.ModuleType):
    """A 'cupy' that is numpy on the host, with the few CUDA calls the backend makes."""

    class cuda:  # noqa: N801 (cupy's name)
        class runtime:  # noqa: N801
            getDeviceCount = staticmethod(lambda: 1)
            memGetInfo = staticmethod(lambda: (8 << 30, 16 << 30))

        class Device:
            id = 0

            def synchronize(self):
                pass

    asnumpy = staticmethod(np.asarray)

    def __getattr__(self, name):
        return getattr(np, name)


@pytest.fixture
def cupy_stand_in(monkeypatch):
    """numpy, scipy.fft and scipy.sparse installed as cupy and cupyx: the cupy backend's own
    code runs on the host."""
    import scipy.fft
    import scipy.sparse

    import bem_solver._xp as bx

    for name, module in {"cupy": _NumpyStandIn("cupy"), "cupyx": types.ModuleType("cupyx"),
                         "cupyx.scipy": types.ModuleType("cupyx.scipy"),
                         "cupyx.scipy.fft": scipy.fft, "cupyx.scipy.sparse": scipy.sparse,
                         "array_api_compat": None, "array_api_compat.cupy": None}.items():
        monkeypatch.setitem(sys.modules, name, module)
    bx._gpu_reason.cache_clear()
    yield
    bx._gpu_reason.cache_clear()


def test_cupy_backend_glue_on_a_numpy_stand_in(cupy_stand_in, monkeypatch):
    """The cupy backend's own code (device selection, cuFFT and cusparse calls, transfers)
    run with numpy, scipy.fft and scipy.sparse standing in for cupy and cupyx: the same
    answer as the CPU path.  It cannot show that cupy computes correctly (the gpu tests do,
    where there is a GPU), only that the backend calls it as the CPU path calls numpy."""
    assert available_devices()["gpu"] == ""
    scene = load_scene("paper-fig3-sparse", ["pillars.E_Pa=1.6e5"])
    stand_in = solve_fft(scene, 16, device="auto", precision="double")
    assert stand_in.diagnostics["device"] == "gpu"
    # the GPU's default warm start nests GPU_WARM_START_LEVELS levels (none)
    assert len(stand_in.diagnostics["warm_start_levels"]) == GPU_WARM_START_LEVELS
    _agree(solve_fft(scene, 16, precision="double", warm_start=GPU_WARM_START_LEVELS),
           stand_in, RTOL_ROUNDOFF, scene.indentation_m)
    # the grid built by the device's library (large grids): the same answer
    monkeypatch.setattr(fft_module, "GPU_GRID_MIN_POINTS", 0)
    _agree(stand_in, solve_fft(scene, 16, device="auto", precision="double"),
           RTOL_ROUNDOFF, scene.indentation_m)
    # Mixed precision: a round-off difference in a float64 part (the sparse product's
    # summation order) can flip a float32 rounding, and the CG then reaches the same
    # tolerance by another path.
    mixed = solve_fft(scene, 16, device="auto")
    assert mixed.converged and mixed.diagnostics["single_precision_applications"] > 0
    for field in ("total_force_N", "centre_pressure_Pa", "contact_radius_m"):
        assert getattr(mixed, field) == pytest.approx(getattr(stand_in, field),
                                                      rel=RTOL_SOLVER), field


# Elastic-pillar scenes (Phi = 0.2 or 0.1 of paper-fig3-sparse, coarse compliances): the
# term's local Love part and pillar coupling (E_p = 0.1 E_s); the mode part and coupling
# alone (E_p = E_s: the CPU updates few clipped cells on their pillars only); the floor
# reached (the term on the tops alone).
ELASTIC = [
    ("soft", ["pillars.surface_fraction=0.2", "load.indentation_um=0.1",
              "pillars.E_Pa=1.6e5"], 16),
    ("same-material", ["pillars.surface_fraction=0.2", "load.indentation_um=0.1"], 16),
    ("floor", ["lens.radius_mm=0.25", "pillars.surface_fraction=0.1", "pillars.E_Pa=1.6e5",
               "load.indentation_um=6"], 8),
]


def _elastic(overrides):
    from fem_reference import PillarKind, modal_compliance

    scene = load_scene("paper-fig3-sparse", overrides)
    return scene, modal_compliance(PillarKind.of_scene(scene), 2, mesh_size=4.0)


def _elastic_gpu_agrees_with_cpu(case):
    """``case`` solved on the device 'gpu' (cupy or its stand-in) and on the CPU, in double
    precision: the same answer to RTOL_ROUNDOFF; (scene, compliance, N)."""
    _, overrides, n = case
    scene, modal = _elastic(overrides)
    gpu = solve_fft(scene, n, device="gpu", pillars="elastic", compliance=modal,
                    precision="double")
    assert gpu.converged and gpu.diagnostics["device"] == "gpu"
    cpu = solve_fft(scene, n, pillars="elastic", compliance=modal, precision="double",
                    warm_start=GPU_WARM_START_LEVELS)
    _agree(cpu, gpu, RTOL_ROUNDOFF, scene.indentation_m)
    return scene, modal, n


@pytest.mark.usefixtures("compliance_cache")
@pytest.mark.parametrize("case", ELASTIC, ids=lambda c: c[0])
def test_elastic_pillar_on_the_cupy_stand_in_gives_the_cpu_answer(cupy_stand_in, case):
    """The elastic pillar's term on the cupy backend (one sparse product over all pillars
    instead of cache-sized chunks, its boxes' transforms by cupyx's FFT, no few-cell updates):
    the CPU path's answer to round-off (RTOL_ROUNDOFF: the same expressions, the sums of a
    product's rows in another order)."""
    scene, modal, n = _elastic_gpu_agrees_with_cpu(case)
    # 'auto' takes the GPU for the elastic pillar too
    auto = solve_fft(scene, n, device="auto", pillars="elastic", compliance=modal)
    assert auto.diagnostics["device"] == "gpu"


@pytest.mark.usefixtures("compliance_cache")
@pytest.mark.parametrize("case", ELASTIC, ids=lambda c: c[0])
def test_elastic_pillar_on_the_strict_namespace_gives_the_numpy_answer(case):
    """The elastic pillar's application through the array API standard alone (its sums
    by the standard's, not einsum): the numpy path's answer to round-off, in double
    precision (in mixed, round-off in a float64 part can flip a float32 rounding: 1.1e-12
    in sigma_0 on 'same-material')."""
    _, overrides, n = case
    scene, modal = _elastic(overrides)
    ref = solve_fft(scene, n, pillars="elastic", compliance=modal, precision="double")
    strict = solve_fft(scene, n, backend=StrictDevice(numpy_primitives=True),
                       pillars="elastic", compliance=modal, precision="double")
    assert ref.converged and strict.converged
    _agree(ref, strict, RTOL_ROUNDOFF, scene.indentation_m)


@pytest.mark.gpu
@pytest.mark.usefixtures("compliance_cache")
@pytest.mark.parametrize("case", ELASTIC, ids=lambda c: c[0])
def test_elastic_pillar_on_the_gpu_gives_the_cpu_answer(case):
    """The elastic pillar set up and applied on a CUDA GPU (its per-cell set-up and its
    near-field pairs built there): the CPU path's answer to round-off, as on the stand-in
    (RTOL_ROUNDOFF; the solve's own tolerance is 1e-8 of the indentation)."""
    _gpu_or_skip()
    pytest.importorskip("skfem", reason="the pillar's compliance is read through scikit-fem")
    _elastic_gpu_agrees_with_cpu(case)


def test_the_elastic_pillar_takes_its_share_of_a_gpus_memory(cupy_stand_in):
    """On a GPU the elastic pillar's term takes device memory beside the operator's
    (GPU_ELASTIC_BYTES_PER_FFT_POINT): a grid that fits the operator alone but not both is
    refused, before any array is built, naming cells_per_diameter; the CPU's limit is its
    own (the stand-in's device has 8 GiB free)."""
    from pillar_xval.scenes import SceneError

    from bem_solver._fft_grid import candidate_side, check_grid_side
    from bem_solver._xp import (GPU_BYTES_PER_FFT_POINT, GPU_ELASTIC_BYTES_PER_FFT_POINT,
                                fft_point_limit)

    be = select_backend("gpu")
    full, shared = fft_point_limit(be, False), fft_point_limit(be, True)
    assert full == (8 << 30) // GPU_BYTES_PER_FFT_POINT
    assert shared == full * GPU_BYTES_PER_FFT_POINT \
        // (GPU_BYTES_PER_FFT_POINT + GPU_ELASTIC_BYTES_PER_FFT_POINT)
    assert fft_point_limit(NumpyDevice(), True) == NumpyDevice().max_fft_points
    scene = load_scene("paper-fig3-sparse", ["pillars.E_Pa=1.6e5"])
    n = 64
    while candidate_side(scene, n) ** 2 <= 4 * shared:  # the first level past the shared limit
        n += max(1, n // 64)
    side = candidate_side(scene, n)
    assert side ** 2 <= 4 * full  # ... that the operator alone would take
    check_grid_side(side, n, full)
    with pytest.raises(SceneError, match=f"cells_per_diameter = {n}"):
        fft_module._refuse_grid(scene, n, be, elastic=True)
