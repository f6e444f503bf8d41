"""Dense influence operators: element forces (N) -> normal displacements (m).

The collocation operator over all elements is

    K[a, b] = (gamma_l + gamma_s) / pi * D(x_a; square_b) / area_b + c_h [pillar(a) == pillar(b)],

Love's coefficient D per unit force plus the Hooke shortening c_h = 4 h / (pi d^2 E_p) of a
pillar under the force of each of its elements (a low-rank term).  Collocation with Love's
formula is symmetric only up to O((b/r)^4) between squares of different orientation, so the
solvers use a symmetric operator: for each pair of orbits one direction is kept,

    Ks[a, b] = K[a, b] if rep(a) < rep(b),  K[b, a] if rep(a) > rep(b),  sym(K) within an orbit,

a change far below the discretisation error that makes the discrete problem an energy
minimisation (solvable exactly by active sets and NNLS).

With forces constant on symmetry orbits (expansion E from representatives to images), the
reduced operator is M = E^T Ks E, computed without forming Ks: for representatives i <= j,
M[i, j] = |orbit(i)| * sum over the images b of j of K(x_i, b), by invariance of the
discretisation under the orbit group (D6 off the centre pillar, D2 on it; the centre
pillar's representatives come first, so its rows only ever meet groups that map its grid onto
itself).  Only the upper triangle is evaluated (as the lower triangle of the transpose, whose
rows the assembly writes contiguously).
"""

from __future__ import annotations

import math
import queue
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from threadpoolctl import threadpool_limits

from pillar_xval.scenes import Scene
from pillar_xval.threads import thread_count

from ._discretise import Discretisation
from ._love import FAR_FIELD_RATIO, love_square_near, unit_force_influence

# Entries evaluated per block: work arrays of ~2 MB, within a core's share of the cache, and
# few enough blocks that their Python overhead (some 20 numpy calls each) stays small: on
# the largest paper scene (2564 unknowns, 29653 images) 685 blocks of 65,536 entries took
# 0.22 s, 148 of 262,144 0.15 s (medians of 3; 1,048,576: 0.50 s).
_BLOCK = 262_144
# Each assembly thread keeps two work arrays of a block.
BYTES_PER_THREAD = 2 * 8.0 * _BLOCK
_NEAR_CHUNK = 8192  # near pairs per evaluation of Love's exact coefficient


def _coefficients(scene: Scene) -> tuple[float, float]:
    return scene.half_space_compliance / math.pi, scene.pillar_spring_compliance


def _influence(px, py, disc: Discretisation, cols: slice | np.ndarray, scale: float):
    """gamma/pi * D / area: displacement at points (px, py) per unit force on image columns."""
    # Loaded squares have area side^2 (covered cells use an equivalent square).
    return scale * unit_force_influence(
        px[:, None], py[:, None], disc.img_x[cols][None, :], disc.img_y[cols][None, :],
        disc.img_angle[cols][None, :], disc.img_side[cols][None, :])


def _block_ranges(disc: Discretisation) -> list[tuple[int, int]]:
    """(j0, j1): ranges of representatives whose images times the representatives 0..j1 make
    ~``_BLOCK`` entries each (the work arrays stay in a core's cache)."""
    n, start = disc.n_unknowns, disc.rep_start
    per_rep = max(np.mean(np.diff(start)), 1.0)
    blocks, j0 = [], 0
    while j0 < n:
        j1 = min(n, j0 + max(1, int(_BLOCK / max(j0, 64) / per_rep)))
        blocks.append((j0, j1))
        j0 = j1
    return blocks


def _weight_runs(weight: np.ndarray, j0: int, j1: int):
    """(a, b, w): runs of representatives j0+a .. j0+b-1 with the same number w of images."""
    w = weight[j0:j1]
    cut = np.flatnonzero(w[1:] != w[:-1]) + 1
    edges = np.concatenate([[0], cut, [len(w)]])
    return [(int(a), int(b), int(w[a])) for a, b in zip(edges[:-1], edges[1:])]


def _lower_column_sums(scene: Scene, disc: Discretisation) -> np.ndarray:
    """T[j, i] (i <= j) = sum over images b of rep j of the Love part of K(x_i, b): the
    displacement at rep i per unit force on every image of rep j.  Upper triangle: zero.
    (T is the transpose of the upper triangle R[i, j] of the reduced operator's row sums.)

    By blocks of representatives j (rows: their images b; columns: the reps i <= j):
    r^2 = |x_b|^2 + |x_i|^2 - 2 x_b . x_i by one matrix product (its rounding, a few eps
    |x|^2, is far below the pairs' r^2 beyond FAR_FIELD_RATIO sides at any size the dense
    limit admits), the far form (r^2 + s^2/24) / r^3 in place in work arrays reused from
    block to block, and on the pairs within FAR_FIELD_RATIO sides of b (candidates from r^2
    with a margin for that rounding, then the exact test of
    :func:`bem_solver._love.unit_force_influence` on their differences) Love's exact rotated
    coefficient (:func:`bem_solver._love.love_square_near`) instead: those entries are zeroed
    in the blocks, evaluated after them in chunks and added to the sums.  The images of a rep
    are contiguous: the sum over them is one reduction per run of reps with the same number
    of images."""
    scale, _ = _coefficients(scene)
    n = disc.n_unknowns
    T = np.zeros((n, n))
    if n == 0:
        return T
    start, weight = disc.rep_start, np.diff(disc.rep_start)
    img_r2 = disc.img_x * disc.img_x + disc.img_y * disc.img_y
    rep_r2 = disc.rep_x * disc.rep_x + disc.rep_y * disc.rep_y
    lhs = np.column_stack([disc.img_x, disc.img_y, img_r2])
    rhs = np.ascontiguousarray(np.vstack([-2.0 * disc.rep_x, -2.0 * disc.rep_y, np.ones(n)]))
    far_coef = (disc.img_side * disc.img_side / 24.0)[:, None]
    near_r2 = FAR_FIELD_RATIO**2 * (disc.img_side * disc.img_side)
    rounding = 64.0 * np.finfo(float).eps * (img_r2.max() + rep_r2.max())
    blocks = _block_ranges(disc)

    size = max((j1 * (start[j1] - start[j0]) for j0, j1 in blocks), default=0)
    buffers = queue.SimpleQueue()  # two work arrays per thread, reused (no page faults)
    threads = thread_count()
    for _ in range(threads):
        buffers.put((np.empty(size), np.empty(size)))

    def work(block):
        bufs = buffers.get()
        try:
            return _block(block, *bufs)
        finally:
            buffers.put(bufs)

    def _block(block, buf_a, buf_b):
        j0, j1 = block
        c0, c1 = start[j0], start[j1]
        shape = (c1 - c0, j1)
        r2 = np.matmul(lhs[c0:c1], rhs[:, :j1], out=buf_a[:shape[0] * shape[1]].reshape(shape))
        r2 += rep_r2[None, :j1]
        # Candidates within the block's largest near radius (plus the product's rounding).
        near = np.flatnonzero(r2 <= near_r2[c0:c1].max() * (1.0 + 1e-9) + rounding)
        with np.errstate(divide="ignore", invalid="ignore"):  # r^2 <= 0: near, replaced
            r3 = np.sqrt(r2, out=buf_b[:shape[0] * shape[1]].reshape(shape))
            r3 *= r2
            r2 += far_coef[c0:c1]
            k = np.divide(r2, r3, out=r2).reshape(-1)
        img, col = np.divmod(near, j1)
        img += c0
        dx = disc.rep_x[col] - disc.img_x[img]
        dy = disc.rep_y[col] - disc.img_y[img]
        keep = (dx * dx + dy * dy <= near_r2[img]) & (col <= disc.img_rep[img])
        k[near[keep]] = 0.0  # Love's exact coefficient is added after the sums
        k = k.reshape(shape)
        S = T[j0:j1, :j1]
        for a, b, w in _weight_runs(weight, j0, j1):
            rows_ab = k[start[j0 + a] - c0:start[j0 + b] - c0]
            np.add.reduce(rows_ab.reshape(b - a, w, j1), axis=1, out=S[a:b])
        S *= scale
        # Columns of this block beyond the diagonal: the upper triangle stays zero.
        T[j0:j1, j0:j1] = np.tril(T[j0:j1, j0:j1])
        return img[keep].astype(np.int32), col[keep].astype(np.int32)

    cos, sin = np.cos(disc.img_angle), np.sin(disc.img_angle)

    def near(part):
        img, col = part
        dx = disc.rep_x[col] - disc.img_x[img]
        dy = disc.rep_y[col] - disc.img_y[img]
        c, s = cos[img], sin[img]
        return scale * love_square_near(dx * c + dy * s, -dx * s + dy * c,
                                        0.5 * disc.img_side[img])

    with threadpool_limits(limits=1, user_api="blas"), ThreadPoolExecutor(threads) as pool:
        img, col = (np.concatenate(a) for a in zip(*pool.map(work, blocks)))
        # Chunks of the near pairs small enough for their temporaries to be reused heap
        # memory (no page faults); their sums go into T as they come.
        cut = range(_NEAR_CHUNK, len(img), _NEAR_CHUNK)
        parts = list(zip(np.split(img, cut), np.split(col, cut)))
        for (i, j), values in zip(parts, pool.map(near, parts)):
            np.add.at(T, (disc.img_rep[i], j), values)
    return T


def reduced_operator(scene: Scene, disc: Discretisation,
                     pillar_block: np.ndarray | None = None) -> np.ndarray:
    """Symmetric reduced operator M = E^T Ks E over the representatives (m/N, weighted).

    ``pillar_block``: the elastic pillars' excess compliance, summed over the images of each
    rep on the pillar of the other (:func:`._elastic_pillar.reduced_block`); it replaces the
    Hooke term."""
    _, c_h = _coefficients(scene)
    w = disc.rep_weight.astype(float)
    # Built as its transpose: the lower triangle MT[j, i] = M[i, j] (i <= j), whose rows
    # the assembly writes contiguously.
    MT = _lower_column_sums(scene, disc)
    if pillar_block is not None:
        MT += np.tril(pillar_block.T)
    elif c_h > 0.0 and len(disc.orbit_size):
        # Images of rep j on the pillar of rep i: only when both lie on the same pillar orbit,
        # then w_j / (pillars in that orbit) of them.  Reps are grouped by orbit: add the
        # term on each orbit's diagonal block (lower triangle of MT).
        per_pillar = w / disc.orbit_size[disc.rep_orbit]
        runs = _runs(disc.rep_orbit)
        if runs is None:
            same = disc.rep_orbit[:, None] == disc.rep_orbit[None, :]
            MT += np.tril(c_h * same * per_pillar[:, None])
        for lo, hi in runs or ():
            MT[lo:hi, lo:hi] += np.tril(c_h * np.broadcast_to(per_pillar[lo:hi, None],
                                                              (hi - lo, hi - lo)))
    MT *= w[None, :]
    _mirror_upper(MT.T)  # the lower triangle onto the upper: M = MT.T = MT
    return MT


def _mirror_upper(M: np.ndarray, block: int = 512) -> None:
    """Copy the strict upper triangle of the square M onto its (zero) lower triangle, in
    place, by blocks (no n x n temporary)."""
    n = len(M)
    for i0 in range(0, n, block):
        i1 = min(n, i0 + block)
        M[i0:i1, :i0] = M[:i0, i0:i1].T
        tile = M[i0:i1, i0:i1]
        lower = np.tril_indices(i1 - i0, -1)
        tile[lower] = tile.T[lower]


def _runs(labels: np.ndarray):
    """(lo, hi) of the runs of equal labels when each label forms one run, else None."""
    cut = np.nonzero(np.diff(labels))[0] + 1
    edges = np.concatenate([[0], cut, [labels.size]])
    runs = list(zip(edges[:-1], edges[1:]))
    return runs if len({labels[lo] for lo, _ in runs}) == len(runs) else None


def full_operator(scene: Scene, disc: Discretisation,
                  pillar_full: np.ndarray | None = None) -> np.ndarray:
    """The symmetric operator Ks over every image element (m/N): the unreduced system;
    ``pillar_full`` (the elastic pillars' block over every image) replaces the Hooke term."""
    scale, c_h = _coefficients(scene)
    K = _influence(disc.img_x, disc.img_y, disc, np.arange(disc.n_elements), scale)
    if pillar_full is not None:
        K += pillar_full
    elif c_h > 0.0:
        K += c_h * (disc.img_pillar[:, None] == disc.img_pillar[None, :])
    rep = disc.img_rep
    return np.where(rep[:, None] < rep[None, :], K,
                    np.where(rep[:, None] > rep[None, :], K.T, 0.5 * (K + K.T)))


def expansion(disc: Discretisation) -> np.ndarray:
    """E (n_elements x n_unknowns): 1 where an image belongs to a representative."""
    E = np.zeros((disc.n_elements, disc.n_unknowns))
    E[np.arange(disc.n_elements), disc.img_rep] = 1.0
    return E
