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
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from scenes import Scene

from ._discretise import Discretisation
from ._love import unit_force_influence

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


def _upper_row_sums(scene: Scene, disc: Discretisation) -> np.ndarray:
    """R[i, j] (i <= j) = sum over images b of rep j of the Love part of K(x_i, b): the
    displacement at rep i per unit force on every image of rep j.  Lower triangle: zero."""
    scale, _ = _coefficients(scene)
    n = disc.n_unknowns
    R = np.zeros((n, n))
    start = disc.rep_start
    per_rep = max(np.mean(np.diff(start)), 1.0) if n else 1.0
    blocks, j0 = [], 0
    while j0 < n:  # blocks of ~_BLOCK entries over the triangle
        j1 = min(n, j0 + max(1, int(_BLOCK / max(j0, 64) / per_rep)))
        blocks.append((j0, j1))
        j0 = j1

    def work(block):
        j0, j1 = block
        cols = slice(start[j0], start[j1])
        k = _influence(disc.rep_x[:j1], disc.rep_y[:j1], disc, cols, scale)
        R[:j1, j0:j1] = np.add.reduceat(k, start[j0:j1] - start[j0], axis=1)

    with ThreadPoolExecutor(_THREADS) as pool:
        list(pool.map(work, blocks))
    return np.triu(R)


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
        # then w_j / (pillars in that orbit) of them.
        same = disc.rep_orbit[:, None] == disc.rep_orbit[None, :]
        per_pillar = w / disc.orbit_size[disc.rep_orbit]
        M += np.triu(c_h * same * per_pillar[None, :])
    M *= w[:, None]
    return M + np.triu(M, 1).T


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
