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
itself).  Only the upper triangle is evaluated.
"""

from __future__ import annotations

import math
import queue
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from scenes import Scene

from ._discretise import Discretisation
from ._love import FAR_FIELD_RATIO, unit_force_influence

# Entries evaluated per block: temporaries of ~2 MB stay in cache.
_BLOCK = 250_000
_THREADS = 2


def _coefficients(scene: Scene) -> tuple[float, float]:
    return scene.half_space_compliance / math.pi, scene.pillar_spring_compliance


def _influence(px, py, disc: Discretisation, cols: slice | np.ndarray, scale: float):
    """gamma/pi * D / area: displacement at points (px, py) per unit force on image columns."""
    # Loaded squares have area side^2 (covered cells use an equivalent square).
    return scale * unit_force_influence(
        px[:, None], py[:, None], disc.img_x[cols][None, :], disc.img_y[cols][None, :],
        disc.img_angle[cols][None, :], disc.img_side[cols][None, :])


def _near_pairs(disc: Discretisation, reps, c0: int, c1: int):
    """(rep i, image b) pairs, b in [c0, c1), i <= rep(b), within ``FAR_FIELD_RATIO`` sides of
    image b, where Love's exact (rotated) coefficient replaces the far form; found with k-d
    trees (``reps``: the tree of the representatives) instead of testing every entry."""
    from scipy.spatial import cKDTree

    side = disc.img_side[c0:c1]
    reach = FAR_FIELD_RATIO * float(side.max(initial=0.0)) * (1.0 + 1e-9)
    imgs = cKDTree(np.column_stack([disc.img_x[c0:c1], disc.img_y[c0:c1]]))
    pairs = imgs.sparse_distance_matrix(reps, reach, output_type="ndarray")
    col, row = pairs["i"].astype(np.int64) + c0, pairs["j"].astype(np.int64)
    # The same test as unit_force_influence: r^2 <= FAR_FIELD_RATIO^2 side^2, exactly.
    dx = disc.rep_x[row] - disc.img_x[col]
    dy = disc.rep_y[row] - disc.img_y[col]
    s = disc.img_side[col]
    keep = (dx * dx + dy * dy <= FAR_FIELD_RATIO**2 * (s * s)) \
        & (row <= disc.img_rep[col])  # the upper triangle only
    return row[keep], col[keep]


def _upper_row_sums(scene: Scene, disc: Discretisation) -> np.ndarray:
    """R[i, j] (i <= j) = sum over images b of rep j of the Love part of K(x_i, b): the
    displacement at rep i per unit force on every image of rep j.  Lower triangle: zero.

    Every entry takes the far form 1/r + s^2 / (24 r^3), in place in work arrays reused from
    block to block, then the near pairs of the block (:func:`_near_pairs`) Love's exact
    rotated coefficient: bit for bit the values of
    :func:`bem_solver._love.unit_force_influence`, without its test of every entry."""
    scale, _ = _coefficients(scene)
    n = disc.n_unknowns
    R = np.zeros((n, n))
    if n == 0:
        return R
    from scipy.spatial import cKDTree

    start = disc.rep_start
    reps = cKDTree(np.column_stack([disc.rep_x, disc.rep_y]))
    far_coef = disc.img_side * disc.img_side / 24.0
    per_rep = max(np.mean(np.diff(start)), 1.0)
    blocks, j0 = [], 0
    while j0 < n:  # blocks of ~_BLOCK entries over the triangle
        j1 = min(n, j0 + max(1, int(_BLOCK / max(j0, 64) / per_rep)))
        blocks.append((j0, j1))
        j0 = j1

    size = max((j1 * (start[j1] - start[j0]) for j0, j1 in blocks), default=0)
    buffers = queue.SimpleQueue()  # two work arrays per thread, reused (no page faults)
    for _ in range(_THREADS):
        buffers.put((np.empty(size), np.empty(size)))

    def work(block):
        bufs = buffers.get()
        try:
            _block(block, *bufs)
        finally:
            buffers.put(bufs)

    def _block(block, buf_x, buf_y):
        j0, j1 = block
        c0, c1 = start[j0], start[j1]
        shape = (j1, c1 - c0)
        dx = np.subtract.outer(disc.rep_x[:j1], disc.img_x[c0:c1],
                               out=buf_x[:shape[0] * shape[1]].reshape(shape))
        dy = np.subtract.outer(disc.rep_y[:j1], disc.img_y[c0:c1],
                               out=buf_y[:shape[0] * shape[1]].reshape(shape))
        np.multiply(dx, dx, out=dx)
        np.multiply(dy, dy, out=dy)
        r2 = np.add(dx, dy, out=dx)
        inv = np.sqrt(r2, out=dy)
        with np.errstate(divide="ignore"):  # r = 0: a near pair, replaced below
            np.divide(1.0, inv, out=inv)
        k = np.multiply(inv, inv, out=r2)
        k *= far_coef[None, c0:c1]
        k += 1.0
        k *= inv
        rows, cols = _near_pairs(disc, reps, c0, c1)
        if rows.size:
            k[rows, cols - c0] = unit_force_influence(
                disc.rep_x[rows], disc.rep_y[rows], disc.img_x[cols], disc.img_y[cols],
                disc.img_angle[cols], disc.img_side[cols])[0]
        k *= scale
        R[:j1, j0:j1] = np.add.reduceat(k, start[j0:j1] - c0, axis=1)
        # Rows of this block below the diagonal: the lower triangle stays zero.
        R[j0:j1, j0:j1] = np.triu(R[j0:j1, j0:j1])

    with ThreadPoolExecutor(_THREADS) as pool:
        list(pool.map(work, blocks))
    return R


def reduced_operator(scene: Scene, disc: Discretisation,
                     pillar_block: np.ndarray | None = None) -> np.ndarray:
    """Symmetric reduced operator M = E^T Ks E over the representatives (m/N, weighted).

    ``pillar_block``: the elastic pillars' excess compliance, summed over the images of each
    rep on the pillar of the other (:func:`._elastic_pillar.reduced_block`); it replaces the
    Hooke term."""
    _, c_h = _coefficients(scene)
    w = disc.rep_weight.astype(float)
    M = _upper_row_sums(scene, disc)
    if pillar_block is not None:
        M += np.triu(pillar_block)
    elif c_h > 0.0 and len(disc.orbit_size):
        # Images of rep j on the pillar of rep i: only when both lie on the same pillar orbit,
        # then w_j / (pillars in that orbit) of them.  Reps are grouped by orbit: add the
        # term on each orbit's diagonal block (upper triangle).
        per_pillar = w / disc.orbit_size[disc.rep_orbit]
        runs = _runs(disc.rep_orbit)
        if runs is None:
            same = disc.rep_orbit[:, None] == disc.rep_orbit[None, :]
            M += np.triu(c_h * same * per_pillar[None, :])
        for lo, hi in runs or ():
            M[lo:hi, lo:hi] += np.triu(c_h * np.broadcast_to(per_pillar[None, lo:hi],
                                                             (hi - lo, hi - lo)))
    M *= w[:, None]
    _mirror_upper(M)
    return M


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
