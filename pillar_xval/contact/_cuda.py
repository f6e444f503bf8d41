"""The constrained CG's vector passes fused into CUDA kernels, for cupy arrays.

Each pass of :func:`pillar_xval.contact._cg.constrained_cg` over the cells (the residual with
the free set, the conjugate direction, the step with its minimum, the gap's update with its
largest change, the new contact set with its entries) is a handful of array operations,
each a kernel launch and, where it ends in a reduction, a copy to the host.  On a GPU at
1e6 cells each launch costs more than its arithmetic, so an iteration's ~40 launches of
vector work take longer than its transforms.  Here each pass is one kernel: its elementwise
part and its reduction in one sweep, the reduction finished in the grid's last block, and
one copy of its result(s) to the host.

Same operations, same bits: every product and sum is written with the round-to-nearest
intrinsics (``__dmul_rn``, ``__dadd_rn``), which the compiler never contracts into a fused
multiply-add, in the order of the array operations they replace (``t * beta + z``, then the
indicator's product; ``(t * -tau) + q``); the reductions are max, min and any, exact in any
order.  So the fused passes give the array passes' values bit for bit (``tests``: both on
the same arrays, marked ``gpu``), and the solve the same iterations.

The kernels are compiled once per process (cupy caches the binary on disk).  A backend
offers them as ``cg_passes`` (:class:`pillar_xval.contact._xp.CupyArrays`); where the
backend has none, the CG runs its array passes.
"""

from __future__ import annotations

import numpy as np

# Threads per block (a multiple of the warp, 32) and the most blocks of a sweep: enough to
# fill a large GPU (132 SMs x 8 blocks on an H100/H200), few enough that the last block
# reduces the partial results in one pass.
THREADS = 256
MAX_BLOCKS = 1024

SOURCE = r"""
__device__ __forceinline__ double nan_max(double a, double b) {
    return (a > b || a != a) ? a : b;
}
__device__ __forceinline__ double nan_min(double a, double b) {
    return (a < b || a != a) ? a : b;
}
template <bool MAX>
__device__ __forceinline__ double combine(double a, double b) {
    return MAX ? nan_max(a, b) : nan_min(a, b);
}

// The block's reduction of v (valid in thread 0); every thread of the block must call it.
template <bool MAX>
__device__ double block_reduce(double v, double identity) {
    __shared__ double shared[32];
    const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
    for (int o = 16; o > 0; o >>= 1) v = combine<MAX>(v, __shfl_down_sync(0xffffffffu, v, o));
    __syncthreads();  // shared[] may still be read by a previous call
    if (lane == 0) shared[warp] = v;
    __syncthreads();
    v = identity;
    if (warp == 0) {
        if (lane < (int)(blockDim.x >> 5)) v = shared[lane];
        for (int o = 16; o > 0; o >>= 1)
            v = combine<MAX>(v, __shfl_down_sync(0xffffffffu, v, o));
    }
    return v;
}

// The grid's reduction of K values per thread into out[0..K): each block writes its partial
// results, and the last block to finish (counted by an atomic counter, which wraps back to
// zero for the next launch) reduces them.
template <int K, bool MAX>
__device__ void grid_reduce(const double (&v)[K], double identity, double* partial,
                            unsigned int* counter, double* out) {
    __shared__ bool last;
    for (int k = 0; k < K; ++k) {
        const double r = block_reduce<MAX>(v[k], identity);
        if (threadIdx.x == 0) partial[k * gridDim.x + blockIdx.x] = r;
    }
    if (threadIdx.x == 0) {
        __threadfence();
        last = atomicInc(counter, gridDim.x - 1) == gridDim.x - 1;
    }
    __syncthreads();
    if (!last) return;
    __threadfence();
    const volatile double* parts = partial;
    for (int k = 0; k < K; ++k) {
        double r = identity;
        for (unsigned int b = threadIdx.x; b < gridDim.x; b += blockDim.x)
            r = combine<MAX>(r, parts[k * gridDim.x + b]);
        r = block_reduce<MAX>(r, identity);
        if (threadIdx.x == 0) out[k] = r;
    }
}

#define SWEEP(i, n) \
    for (long long i = blockIdx.x * (long long)blockDim.x + threadIdx.x; i < (n); \
         i += (long long)gridDim.x * blockDim.x)

extern "C" {

// max(gap * active, -gap, 0) over the cells; free = active | (gap < 0).
__global__ void residual_free(const double* gap, const bool* active, bool* free_set,
                              long long n, double* partial, unsigned int* counter,
                              double* out) {
    double m[1] = {0.0};
    SWEEP(i, n) {
        const double g = gap[i];
        const bool on = active[i];
        m[0] = nan_max(m[0], nan_max(__dmul_rn(g, (double)on), -g));
        free_set[i] = on || (g < 0.0);
    }
    grid_reduce<1, true>(m, 0.0, partial, counter, out);
}

// t = (t * beta + z) * free.
__global__ void conjugate(double* t, const double* z, const bool* free_set, double beta,
                          long long n) {
    SWEEP(i, n) {
        t[i] = __dmul_rn(__dadd_rn(__dmul_rn(t[i], beta), z[i]), (double)free_set[i]);
    }
}

// q_new = (t * -tau) + q, and its minimum (identity: +inf, given).
__global__ void step(double* q_new, const double* q, const double* t, double minus_tau,
                     double identity, long long n, double* partial, unsigned int* counter,
                     double* out) {
    double m[1] = {identity};
    SWEEP(i, n) {
        const double v = __dadd_rn(__dmul_rn(t[i], minus_tau), q[i]);
        q_new[i] = v;
        m[0] = nan_min(m[0], v);
    }
    grid_reduce<1, false>(m, identity, partial, counter, out);
}

// q = max(q, 0).
__global__ void clip(double* q, long long n) {
    SWEEP(i, n) {
        if (q[i] <= 0.0) q[i] = 0.0;  // cupy.maximum's: -0.0 to +0.0, NaN kept
    }
}

// w = w * tau; gap = gap - w; and max |w|.
__global__ void update_gap(double* w, double* gap, double tau, long long n, double* partial,
                           unsigned int* counter, double* out) {
    double m[1] = {0.0};
    SWEEP(i, n) {
        const double ww = __dmul_rn(w[i], tau);
        w[i] = ww;
        gap[i] = __dsub_rn(gap[i], ww);
        m[0] = nan_max(m[0], fabs(ww));
    }
    grid_reduce<1, true>(m, 0.0, partial, counter, out);
}

// The same, then gap = gap + c: max |w| and max |c|.
__global__ void update_gap_clipped(double* w, double* gap, const double* c, double tau,
                                   long long n, double* partial, unsigned int* counter,
                                   double* out) {
    double m[2] = {0.0, 0.0};
    SWEEP(i, n) {
        const double ww = __dmul_rn(w[i], tau);
        const double cc = c[i];
        w[i] = ww;
        gap[i] = __dadd_rn(__dsub_rn(gap[i], ww), cc);
        m[0] = nan_max(m[0], fabs(ww));
        m[1] = nan_max(m[1], fabs(cc));
    }
    grid_reduce<2, true>(m, 0.0, partial, counter, out);
}

// new_active = q > 0, and 1 where a cell entered (in new_active, not in active).
__global__ void new_set(bool* new_active, const double* q, const bool* active, long long n,
                        double* partial, unsigned int* counter, double* out) {
    double m[1] = {0.0};
    SWEEP(i, n) {
        const bool on = q[i] > 0.0;
        new_active[i] = on;
        if (on && !active[i]) m[0] = 1.0;
    }
    grid_reduce<1, true>(m, 0.0, partial, counter, out);
}

}
"""

KERNELS = ("residual_free", "conjugate", "step", "clip", "update_gap", "update_gap_clipped",
           "new_set")


class CudaPasses:
    """The CG's passes (:class:`pillar_xval.contact._cg.ArrayPasses`'s methods) as one fused
    kernel each, on contiguous cupy arrays of float64 (pressures, gaps) and bool (sets);
    unweighted residuals only (the CG uses the array passes with ``weights``)."""

    def __init__(self, cupy):
        self._cp = cupy
        module = cupy.RawModule(code=SOURCE)
        self._kernel = {name: module.get_function(name) for name in KERNELS}
        self._partial = cupy.empty(2 * MAX_BLOCKS, dtype=cupy.float64)
        self._counter = cupy.zeros(1, dtype=cupy.uint32)
        self._out = cupy.zeros(2, dtype=cupy.float64)

    def _launch(self, name, n: int, *args, reduce: bool = True) -> None:
        """``name`` over ``n`` cells with ``args`` (its reduction's buffers appended)."""
        blocks = max(1, min(MAX_BLOCKS, -(-n // THREADS)))
        tail = (self._partial, self._counter, self._out) if reduce else ()
        self._kernel[name]((blocks,), (THREADS,), (*args, *tail))

    def residual(self, gap, active, n: int, free) -> float:
        self._launch("residual_free", n, gap, active, free, np.int64(n))
        return float(self._out[0])

    def conjugate(self, t, beta: float, z, free, n: int) -> None:
        self._launch("conjugate", n, t, z, free, np.float64(beta), np.int64(n), reduce=False)

    def step(self, q_new, q, tau: float, t, n: int) -> float:
        self._launch("step", n, q_new, q, t, np.float64(-tau), np.float64(np.inf),
                     np.int64(n))
        return float(self._out[0])

    def clip(self, q, n: int) -> None:
        self._launch("clip", n, q, np.int64(n), reduce=False)

    def negatives(self, q, n: int):
        return self._cp.nonzero(q < 0.0)[0]

    def update_gap(self, gap, w, tau: float, clip_gap, n: int) -> float:
        if clip_gap is None:
            self._launch("update_gap", n, w, gap, np.float64(tau), np.int64(n))
            return float(self._out[0])
        self._launch("update_gap_clipped", n, w, gap, clip_gap, np.float64(tau), np.int64(n))
        largest = self._out.get()
        return float(largest[0]) + float(largest[1])

    def new_set(self, new_active, q, active, n: int) -> bool:
        self._launch("new_set", n, new_active, q, active, np.int64(n))
        return float(self._out[0]) > 0.0
