"""The constrained CG's fused CUDA passes (pillar_xval.contact._cuda) against its array passes
on the same cupy arrays: the same values bit for bit, since each kernel does the same
round-to-nearest operations in the same order and its reductions (max, min, any) are exact
in any order; and a solve with either gives the same iterations and, where no sum of the
solve runs in an unfixed order (rigid pillars), the same pressures.  Marked
``gpu``: skipped, with the reason, without cupy and a CUDA GPU; the kernels' compilation is
checked wherever cupy's NVRTC is (no GPU needed)."""

from __future__ import annotations

import numpy as np
import pytest

from bem_solver._xp import available_devices
from pillar_xval.contact._cg import ArrayPasses
from pillar_xval.contact._xp import one_piece

# 1 cell; fewer cells than one block; more than MAX_BLOCKS x THREADS (each thread loops).
SIZES = (1, 1000, 300_001)


@pytest.fixture(scope="module")
def backend():
    reason = available_devices()["gpu"]
    if reason:
        pytest.skip(reason)
    from bem_solver._xp import CupyDevice

    return CupyDevice()


def _vectors(be, n, seed):
    rng = np.random.default_rng(seed)
    gap = rng.normal(size=n)
    gap[rng.random(n) < 0.3] = 0.0
    q = np.maximum(rng.normal(size=n), 0.0)
    return {name: be.asarray(v) for name, v in {
        "gap": gap, "q": q, "t": rng.normal(size=n), "z": rng.normal(size=n),
        "w": rng.normal(size=n) * 1e-3, "c": rng.normal(size=n) * 1e-6,
        "active": q > 0.0, "free": rng.random(n) < 0.6}.items()}


def _copy(v):
    return {k: a.copy() for k, a in v.items()}


def _equal(be, a, b):
    """Equal arrays (values; NaN equal to NaN), compared on the host."""
    np.testing.assert_array_equal(be.to_numpy(a), be.to_numpy(b))


@pytest.mark.gpu
@pytest.mark.parametrize("n", SIZES)
def test_each_fused_pass_equals_the_array_pass(backend, n):
    fused, arrays = backend.cg_passes, ArrayPasses(backend.xp, one_piece)
    assert fused is not None
    v = _vectors(backend, n, n)
    a, b = _copy(v), _copy(v)
    assert fused.residual(a["gap"], a["active"], n, a["free"]) \
        == arrays.residual(b["gap"], b["active"], n, b["free"])
    _equal(backend, a["free"], b["free"])
    fused.conjugate(a["t"], 0.37, a["z"], a["free"], n)
    arrays.conjugate(b["t"], 0.37, b["z"], b["free"], n)
    _equal(backend, a["t"], b["t"])
    qa, qb = backend.xp.empty_like(a["q"]), backend.xp.empty_like(b["q"])
    low = fused.step(qa, a["q"], 0.8, a["t"], n)
    assert low == arrays.step(qb, b["q"], 0.8, b["t"], n)
    _equal(backend, qa, qb)
    _equal(backend, fused.negatives(qa, n), arrays.negatives(qb, n))
    fused.clip(qa, n)
    arrays.clip(qb, n)
    _equal(backend, qa, qb)
    assert float(backend.xp.min(qa)) >= 0.0
    for clip_gap in (None, "c"):
        ca = None if clip_gap is None else a[clip_gap]
        cb = None if clip_gap is None else b[clip_gap]
        assert fused.update_gap(a["gap"], a["w"], 0.6, ca, n) \
            == arrays.update_gap(b["gap"], b["w"], 0.6, cb, n)
        _equal(backend, a["gap"], b["gap"])
        _equal(backend, a["w"], b["w"])
    na, nb = backend.xp.zeros_like(a["active"]), backend.xp.zeros_like(b["active"])
    assert fused.new_set(na, qa, a["active"], n) == arrays.new_set(nb, qb, b["active"], n)
    _equal(backend, na, nb)
    # no cell entered: the same set again
    assert fused.new_set(na, qa, na.copy(), n) is False


@pytest.mark.gpu
@pytest.mark.parametrize("overrides", [["pillars.rigid=true"], []], ids=["rigid", "hooke"])
def test_a_solve_with_the_fused_passes_is_the_array_passes_solve(overrides):
    if available_devices()["gpu"]:
        pytest.skip(available_devices()["gpu"])
    from bem_solver._fft import solve_fft
    from bem_solver._xp import CupyDevice
    from pillar_xval.scenes import load_scene

    scene = load_scene("paper-fig3-dense", overrides)
    runs = [solve_fft(scene, 24, backend=CupyDevice(fused=fused)) for fused in (True, False)]
    assert runs[0].iterations == runs[1].iterations
    if overrides:  # rigid pillars: every sum of the solve in a fixed order, the same bits
        assert runs[0].total_force_N == runs[1].total_force_N
        np.testing.assert_array_equal(runs[0].fields["pressure_Pa"],
                                      runs[1].fields["pressure_Pa"])
    else:  # the Hooke term's forces of a step's clipped cells are atomic adds, in no fixed
        # order on a GPU: F_T moved by 1.2e-13 and 3.2e-13 relative between the two solves
        # on an H200 (the solve's own tolerance is 1e-8 of the indentation)
        assert runs[0].total_force_N == pytest.approx(runs[1].total_force_N, rel=1e-12)


def test_the_kernels_compile_without_a_gpu():
    """The CUDA source of the fused passes compiles with NVRTC, which needs cupy's NVRTC
    bindings and the NVRTC library but no GPU (a scratch environment with cupy-cuda12x and
    nvidia-cuda-nvrtc-cu12 checks it on a machine without one); skipped where they are
    missing."""
    nvrtc = pytest.importorskip("cupy_backends.cuda.libs.nvrtc",
                                reason="cupy's NVRTC bindings")
    from pillar_xval.contact._cuda import SOURCE

    try:
        program = nvrtc.createProgram(SOURCE, "passes.cu", [], [])
    except Exception as exc:  # no NVRTC library: nothing to compile with here
        pytest.skip(f"NVRTC unavailable ({type(exc).__name__})")
    try:
        nvrtc.compileProgram(program, ["-arch=compute_70"])
    except Exception:
        pytest.fail(nvrtc.getProgramLog(program))
